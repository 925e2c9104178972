"""Sections of a summary for people: the same text in summary(), summary.json and reports.

A result describes itself as a list of Sections (a title and lines); `render` makes the text
of summary(), output writers store them in summary.json, and the reports render them as
they are, so that what a user reads is written in one place.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass


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
