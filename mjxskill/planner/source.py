"""Positions in PDDL text, so that errors found after parsing can still name a line and column.

The `pddl` package's semantic checks (and ours) work on its object model, which keeps no source
positions; this module finds the offending text again by pattern, ignoring comments.
"""

from __future__ import annotations

import re
from typing import Sequence

from mjxskill.planner.errors import PDDLError

_COMMENT = re.compile(r";[^\n]*")


class Source:
    """One PDDL text (``kind`` is ``"domain"`` or ``"problem"``) with position look-ups."""

    def __init__(self, kind: str, text: str):
        self.kind = kind
        self.text = text
        # Comments blanked out (same length) so that offsets stay valid and we never match
        # inside a comment.
        self.code = _COMMENT.sub(lambda m: " " * len(m.group()), text)

    def line_column(self, offset: int) -> tuple[int, int]:
        """1-based (line, column) of a character offset."""
        line = self.text.count("\n", 0, offset) + 1
        column = offset - (self.text.rfind("\n", 0, offset) + 1) + 1
        return line, column

    def error(self, what: str, offset: int | None) -> PDDLError:
        if offset is None:
            return PDDLError(self.kind, None, None, what)
        return PDDLError(self.kind, *self.line_column(offset), what)

    def find_tokens(self, tokens: Sequence[str], span: tuple[int, int] | None = None,
                    parenthesized: bool = True) -> int | None:
        """Offset of the first occurrence of ``tokens`` (as ``(tok tok ...)`` when
        ``parenthesized``, else as a bare token sequence), case-insensitively, within ``span``."""
        body = r"\s+".join(re.escape(t) for t in tokens)
        if parenthesized:
            pattern = r"\(\s*" + body + r"(?=[\s()])"
        else:
            pattern = r"(?<![\w?:-])" + body + r"(?![\w-])"
        start, end = span if span is not None else (0, len(self.code))
        match = re.compile(pattern, re.IGNORECASE).search(self.code, start, end)
        return None if match is None else match.start()

    def locate(self, candidates: Sequence[tuple[Sequence[str], bool]],
               span: tuple[int, int] | None = None) -> int | None:
        """First hit among ``(tokens, parenthesized)`` candidates, else ``span``'s start."""
        for tokens, parenthesized in candidates:
            offset = self.find_tokens(tokens, span, parenthesized)
            if offset is not None:
                return offset
        return None if span is None else span[0]

    def section(self, head: Sequence[str]) -> tuple[int, int] | None:
        """Span (start, end) of the parenthesized form that begins with ``head``, e.g.
        ``(":action", "pick")`` or ``(":init",)``."""
        start = self.find_tokens(head)
        if start is None:
            return None
        depth = 0
        for i in range(start, len(self.code)):
            char = self.code[i]
            if char == "(":
                depth += 1
            elif char == ")":
                depth -= 1
                if depth == 0:
                    return start, i + 1
        return start, len(self.code)
