"""The fenced code blocks of the README and docs/*.md, with the docs-test directives written before them.

A directive is an HTML comment on its own line, before a block (blank lines between are allowed, text is not):

* ``<!-- docs-test: skip (REASON) -->``: the ``bash``/``python`` block below is not run here; REASON says why
  (a live camera, a remote cluster, your own files, the full 20-minute benchmark).
* ``<!-- docs-test: output -->``: the block below is what the run block above it prints on stdout, exactly.
* ``<!-- docs-test: warns NAME -->``: the ``python`` block below must raise a warning of the class NAME.

Every ``bash`` and ``python`` block without ``skip`` is run (docs/development.md, "The docs test").
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

__all__ = ["RUNNABLE", "Block", "DocsTestError", "read_blocks"]

RUNNABLE = ("bash", "python")
_DIRECTIVE = re.compile(r"^\s*<!--\s*docs-test:\s*(?P<name>[a-z]+)\s*(?P<arg>.*?)\s*-->\s*$")
_NAMES = ("skip", "output", "warns")


class DocsTestError(ValueError):
    """A directive that is malformed, unknown or not followed by a block."""


@dataclass(frozen=True)
class Block:
    """One fenced block: its page, the line of its opening fence, its language, text and directive."""

    page: Path
    line: int
    lang: str
    text: str
    directive: str = ""
    arg: str = ""

    @property
    def where(self) -> str:
        return f"{self.page.parent.name + '/' if self.page.parent.name == 'docs' else ''}{self.page.name}:{self.line}"

    @property
    def runnable(self) -> bool:
        return self.lang in RUNNABLE and self.directive != "skip"


def read_blocks(page: Path) -> list[Block]:
    """The fenced blocks of ``page`` in order, each with the directive written just before it (if any).

    >>> import tempfile
    >>> p = Path(tempfile.mkdtemp()) / "x.md"
    >>> _ = p.write_text("<!-- docs-test: skip (a camera) -->\\n```bash\\nls\\n```\\n", encoding="utf-8")
    >>> [(b.lang, b.directive, b.arg, b.text) for b in read_blocks(p)]
    [('bash', 'skip', 'a camera', 'ls\\n')]
    """
    out: list[Block] = []
    pending: tuple[str, str, int] | None = None
    body: list[str] | None = None
    lang, start = "", 0
    for number, line in enumerate(page.read_text(encoding="utf-8").splitlines(keepends=True), 1):
        if body is not None:
            if line.startswith("```"):
                name, arg = (pending[0], pending[1]) if pending else ("", "")
                out.append(Block(page, start, lang, "".join(body), name, arg))
                body, pending = None, None
            else:
                body.append(line)
            continue
        match = _DIRECTIVE.match(line)
        if match:
            if pending:
                raise DocsTestError(f"{page.name}:{pending[2]}: a docs-test directive not followed by a block")
            name, arg = match["name"], match["arg"]
            if name not in _NAMES:
                raise DocsTestError(f"{page.name}:{number}: unknown docs-test directive {name!r}; known: {_NAMES}")
            if name == "skip":
                reason = re.fullmatch(r"\((.+)\)", arg)
                if not reason or not reason[1].strip():
                    raise DocsTestError(f"{page.name}:{number}: `docs-test: skip` needs a reason: skip (why)")
                arg = reason[1].strip()
            if name == "warns" and not re.fullmatch(r"[A-Za-z_]\w*", arg):
                raise DocsTestError(f"{page.name}:{number}: `docs-test: warns` needs a warning class name")
            pending = (name, arg, number)
        elif line.startswith("```"):
            body, lang, start = [], line.strip()[3:].strip(), number
        elif line.strip() and pending:
            raise DocsTestError(f"{page.name}:{pending[2]}: a docs-test directive not followed by a block")
    if pending:
        raise DocsTestError(f"{page.name}:{pending[2]}: a docs-test directive not followed by a block")
    if body is not None:
        raise DocsTestError(f"{page.name}:{start}: a fenced block that is never closed")
    return out
