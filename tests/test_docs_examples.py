"""The documentation's commands and snippets run as written (issue 34): every fenced ``bash``/``python`` block of
README.md and docs/*.md runs, page by page and in order, in a fresh folder beside a ``shared`` folder that links
the real scenes and models (so ``../shared/data/...`` means what it means beside a checkout); a block marked
``<!-- docs-test: output -->`` is compared with what the block before it printed; a block marked
``<!-- docs-test: skip (REASON) -->`` is not run, and says why. Directives: tests/helpers/docblocks.py."""

from __future__ import annotations

import contextlib
import io
import os
import re
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from tests.conftest import REPO, SHARED_DATA, SHARED_MODELS
from tests.helpers.docblocks import RUNNABLE, Block, DocsTestError, read_blocks

PAGES = sorted([REPO / "README.md", *(REPO / "docs").glob("*.md")])
_ID = {p: p.relative_to(REPO).as_posix() for p in PAGES}


def _page_blocks(page: Path) -> list[Block]:
    return read_blocks(page)


@pytest.mark.parametrize("page", PAGES, ids=_ID.get)
def test_every_block_is_run_or_says_why_not(page):
    blocks = _page_blocks(page)
    problems = []
    previous: Block | None = None
    for block in blocks:
        if block.directive == "output":
            if previous is None or not previous.runnable:
                problems.append(f"{block.where}: an output block that follows no run block")
        elif block.directive and block.lang not in RUNNABLE:
            problems.append(f"{block.where}: `docs-test: {block.directive}` on a {block.lang or 'plain'} block")
        elif block.directive == "warns" and block.lang != "python":
            problems.append(f"{block.where}: `docs-test: warns` on a {block.lang} block")
        first = block.text.lstrip().splitlines()[0] if block.text.strip() else ""
        if block.lang == "" and block.directive != "output" and re.match(r"(\$ |python -m |pip install)", first):
            problems.append(f"{block.where}: a command in an untagged block: tag it bash (run or skip with a "
                            "reason), or text for a synopsis")
        if block.lang in RUNNABLE:
            previous = block
        elif block.directive != "output":
            previous = None
    assert not problems, "\n".join(problems)


def _needs(blocks: list[Block]) -> None:
    text = "".join(b.text for b in blocks if b.runnable)
    if "../shared/data" in text and SHARED_DATA is None:
        pytest.skip("its examples read ../shared/data, not present here")
    if "shared/models" in text and SHARED_MODELS is None:
        pytest.skip("its examples read ../shared/models, not present here")


def _workdir(tmp_path: Path) -> Path:
    """``tmp/work``, a checkout as a reader has it: links to the repository's files and folders (the commands run
    from the checkout's root, e.g. ``benchmarks/results/report.json``; what they write lands in ``tmp/work``),
    beside ``tmp/shared/{data,models}`` linking the shared folders (``../shared/data`` as beside a checkout)."""
    shared = tmp_path / "shared"
    shared.mkdir()
    for name, target in (("data", SHARED_DATA), ("models", SHARED_MODELS)):
        if target is not None:
            (shared / name).symlink_to(target, target_is_directory=True)
    work = tmp_path / "work"
    work.mkdir()
    for entry in REPO.iterdir():
        if not entry.name.startswith(".") and entry.name not in ("stereo_out", "bench_out"):
            (work / entry.name).symlink_to(entry, target_is_directory=entry.is_dir())
    return work


def _run_bash(block: Block, work: Path, env: dict[str, str]) -> str:
    done = subprocess.run(["bash", "-euo", "pipefail", "-c", block.text], cwd=work, env=env, capture_output=True,
                          text=True, timeout=900)
    assert done.returncode == 0, (f"{block.where}: exit code {done.returncode}\n--- the block:\n{block.text}"
                                  f"--- stderr (end):\n{done.stderr[-3000:]}")
    return done.stdout


def _run_python(block: Block, namespace: dict) -> str:
    out = io.StringIO()
    with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stdout(out):
        warnings.simplefilter("always")
        try:
            exec(compile(block.text, f"<{block.where}>", "exec"), namespace)  # noqa: S102 - the docs' own code
        except Exception as exc:  # the block's own failure, named by its place in the docs
            raise AssertionError(f"{block.where}: {type(exc).__name__}: {exc}\n--- the block:\n{block.text}") from exc
    if block.directive == "warns":
        names = [w.category.__name__ for w in caught]
        assert block.arg in names, f"{block.where}: expected a {block.arg}, got {names or 'no warning'}"
    return out.getvalue()


@pytest.mark.parametrize("page", PAGES, ids=_ID.get)
def test_the_examples_run_as_written(page, tmp_path, monkeypatch):
    try:
        blocks = _page_blocks(page)
    except DocsTestError as exc:
        pytest.fail(str(exc))
    if not any(b.runnable for b in blocks):
        pytest.skip(f"{_ID[page]} has no block to run")
    _needs(blocks)
    work = _workdir(tmp_path)
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [env.get("PYTHONPATH")])])
    env["XDG_CACHE_HOME"] = str(tmp_path / "cache")  # nothing fetched before: what a new user has
    env["MPLBACKEND"] = "Agg"
    if SHARED_MODELS is not None:
        env["STEREO_CLASSIC_MODELS"] = str(SHARED_MODELS)
    for key in ("XDG_CACHE_HOME", "MPLBACKEND", "STEREO_CLASSIC_MODELS"):
        if key in env:
            monkeypatch.setenv(key, env[key])
    monkeypatch.chdir(work)
    namespace: dict = {"__name__": "__docs__"}
    printed: str | None = None
    for block in blocks:
        if block.directive == "output":
            assert printed is not None, f"{block.where}: output of a block that did not run"
            assert printed == block.text, f"{block.where}: the block above printed\n{printed}\nnot\n{block.text}"
            continue
        printed = None
        if not block.runnable:
            continue
        printed = _run_bash(block, work, env) if block.lang == "bash" else _run_python(block, namespace)
