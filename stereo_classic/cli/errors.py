"""The command line's own error: a command line that parses but makes no sense (exit code 2)."""

from __future__ import annotations

__all__ = ["UsageError"]


class UsageError(ValueError):
    """A command line that parses but makes no sense (exit code 2)."""
