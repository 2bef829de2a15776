"""docs/cli.md and the commands' ``--help`` agree (issue 34): every option of every command appears in the docs,
every option the docs name exists, and the choices the docs list (``--paths 3|4|8``) are the command's."""

from __future__ import annotations

import contextlib
import importlib
import io
import re

import pytest

from tests.conftest import REPO

CLI_MD = REPO / "docs" / "cli.md"
GUIDE_MD = REPO / "docs" / "guide.md"
ROS_MD = REPO / "docs" / "ros.md"

#: (label, module with main(argv), the argv before --help, the pages that document it)
COMMANDS = [
    ("stereo_classic", "stereo_classic.cli", [], (CLI_MD,)),
    ("stereo_classic run", "stereo_classic.cli", ["run"], (CLI_MD,)),
    ("stereo_classic disparity", "stereo_classic.cli", ["disparity"], (CLI_MD,)),
    ("stereo_classic calibrate", "stereo_classic.cli", ["calibrate"], (CLI_MD,)),
    ("stereo_classic guide", "stereo_classic.cli", ["guide"], (GUIDE_MD, CLI_MD)),
    ("stereo_classic ros", "stereo_classic.cli", ["ros"], (ROS_MD, CLI_MD)),
    ("detectors", "detectors.cli", [], (CLI_MD,)),
    ("detectors fetch", "detectors.cli", ["fetch"], (CLI_MD,)),
    ("detectors detect", "detectors.cli", ["detect"], (CLI_MD,)),
    ("benchmarks", "benchmarks.__main__", [], (CLI_MD,)),
    *[(f"benchmarks.{m}", f"benchmarks.{m}", [], (CLI_MD,))
      for m in ("sgm_speed", "density", "kitti_objects", "guide_ground", "guide_cost", "throughput", "pair_check",
                "render", "detector_latency", "pipeline_table", "kernel_profile")],
    ("benchmarks.objects", "benchmarks.object_errors", [], (CLI_MD,)),  # objects' __main__ runs object_errors.main
]
#: Modules run with ``python -m`` that are not commands for a user: memprobe is the benchmark's own child process.
INTERNAL = {"memprobe"}
_IDS = [c[0] for c in COMMANDS]
_OPTION = re.compile(r"(?<![\w-])(--?[A-Za-z][\w-]*)")


def help_text(module: str, argv: list[str]) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        try:
            code = importlib.import_module(module).main([*argv, "--help"])
        except SystemExit as exc:  # argparse's own exit, where main lets it through: the same exit code
            code = exc.code
    assert code == 0, f"{module} {argv} --help exited {code}"
    return out.getvalue()


def options_of(text: str) -> dict[str, str]:
    """{option: its metavar or choices as written in the help} of every option entry of an argparse help text.

    >>> options_of("options:\\n  -o DIR, --output DIR  out\\n  --paths {3,4,8}       n\\n  --ply, --no-ply  x\\n")
    {'-o': 'DIR', '--output': 'DIR', '--paths': '{3,4,8}', '--ply': '', '--no-ply': ''}
    """
    found: dict[str, str] = {}
    for line in text.splitlines():
        entry = re.match(r"^ {2}(-\S.*?)(?: {2,}|$)", line)
        if not entry:
            continue
        for part in entry[1].split(", "):
            name, _, meta = part.partition(" ")
            if _OPTION.fullmatch(name):
                found[name] = meta.split(" ")[0] if meta else ""
    found.pop("-h", None)
    found.pop("--help", None)
    return found


def _named(option: str, text: str) -> bool:
    return re.search(rf"(?<![\w-]){re.escape(option)}(?![\w-])", text) is not None


def _choices(meta: str) -> set[str] | None:
    """The choices a help entry shows ({3,4,8} or census+grad|census|sad), None for a placeholder (PX|off)."""
    if meta.startswith("{"):
        return set(meta.strip("{}").split(","))
    if "|" in meta and meta.lower() == meta:
        return set(meta.split("|"))
    return None


@pytest.fixture(scope="module")
def helps() -> dict[str, dict[str, str]]:
    return {label: options_of(help_text(module, argv)) for label, module, argv, _ in COMMANDS}


@pytest.mark.parametrize("label", _IDS)
def test_every_option_of_the_command_is_documented(label, helps):
    pages = next(c[3] for c in COMMANDS if c[0] == label)
    text = "".join(p.read_text(encoding="utf-8") for p in pages)
    missing = [o for o in helps[label] if not _named(o, text)]
    assert helps[label] or label.startswith("benchmarks.detector_latency"), f"{label}: no option read from --help"
    assert not missing, f"{label}: options of --help not in {', '.join(p.name for p in pages)}: {missing}"


def test_every_option_cli_md_names_exists(helps):
    known = set().union(*helps.values()) | {"--help"}
    text = CLI_MD.read_text(encoding="utf-8")
    code = "\n".join(re.findall(r"`([^`]*)`", text))  # options are written as code
    named = set(re.findall(r"(?<![\w-])(--[a-z][\w-]*)", code))
    unknown = sorted(named - known)
    assert not unknown, f"docs/cli.md names options no command has: {unknown}"


def test_the_choices_cli_md_lists_are_the_commands(helps):
    shown: dict[str, list[set[str]]] = {}  # a flag may have other choices in another command (sgm_speed's --cost)
    for options in helps.values():
        for option, meta in options.items():
            if _choices(meta) is not None:
                shown.setdefault(option, []).append(_choices(meta))
    text = CLI_MD.read_text(encoding="utf-8").replace("\\|", "|")
    wrong = []
    for option, listed in re.findall(r"`(--[a-z][\w-]*) ([a-z0-9+]+(?:\|[a-z0-9+]+)+)", text):
        if option in shown and set(listed.split("|")) not in shown[option]:
            have = " or ".join("|".join(sorted(c)) for c in shown[option])
            wrong.append(f"{option} {listed}: the commands have {have}")
    assert not wrong, "docs/cli.md lists other choices than the commands:\n" + "\n".join(wrong)


def test_the_comparison_reads_what_it_compares(helps):
    """The test above is not empty: it reads the matcher's cost and paths, and a wrong list fails it."""
    assert _choices(helps["stereo_classic run"]["--paths"]) == {"3", "4", "8"}
    assert {"census+grad", "census", "sad"} <= _choices(helps["stereo_classic disparity"]["--cost"])
    assert not _named("--fill-holes", "`--no-fill-holes`") and _named("--no-fill-holes", "`--no-fill-holes`")


def test_every_benchmark_command_is_in_cli_md_and_in_this_test():
    """Each module of benchmarks/ that runs as ``python -m benchmarks.NAME`` has a row in cli.md's table of commands,
    and its options are compared above (a new command cannot go undocumented)."""
    modules = sorted(p.stem for p in (REPO / "benchmarks").glob("*.py") if not p.stem.startswith("_")
                     and p.stem not in INTERNAL and '\nif __name__ == "__main__"' in p.read_text(encoding="utf-8"))
    table = CLI_MD.read_text(encoding="utf-8").split("\n## ", 1)[0]  # the table at the top of the page
    assert [m for m in modules if f"`python -m benchmarks.{m}" not in table] == []
    assert [m for m in modules if f"benchmarks.{m}" not in _IDS and m != "object_errors"] == []
