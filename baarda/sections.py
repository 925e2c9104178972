"""Sections of a summary for people: the same text in summary(), summary.json and reports.

A result describes itself as a list of Sections (a title and lines); `render` makes the text
of summary(), output writers store them in summary.json, and the reports render them as
they are, so that what a user reads is written in one place.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

#: the lines of one list a summary shows (a camera or a test per line): a block of thousands
#: of cameras lists the first ones and counts the rest, which the result's files hold
MAX_LISTED = 20


@dataclass(frozen=True)
class Section:
    title: str
    lines: tuple[str, ...]

    def to_dict(self) -> dict:
        return {"title": self.title, "lines": list(self.lines)}

    @classmethod
    def from_dict(cls, d: dict) -> Section:
        return cls(str(d.get("title", "")), tuple(str(x) for x in d.get("lines", [])))


def section(title: str, lines: Iterable[str]) -> Section:
    return Section(title, tuple(lines))


def at_most(lines: list[str], rest: str, limit: int = MAX_LISTED) -> list[str]:
    """`lines` when there are at most `limit` (or one more: a line in place of a line), else
    the first `limit` and one line "... and N more REST" for the others."""
    if len(lines) <= limit + 1:
        return lines
    return lines[:limit] + [f"... and {len(lines) - limit} more {rest}"]


def render(sections: Iterable[Section], width: int = 60) -> str:
    """Text of sections: each title underlined, sections separated by a blank line."""
    out: list[str] = []
    for s in sections:
        if out:
            out.append("")
        if s.title:
            out += [s.title, "=" * width]
        out += list(s.lines)
    return "\n".join(out)
