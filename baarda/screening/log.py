"""The screening log: what each stage removed, where, and why."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import pandas as pd

STAGES = {1: "photo pairs", 2: "strip formation", 3: "control", 0: "chain",
          4: "bundle snooping"}


@dataclass
class Entry:
    """One decision.  `what` is 'image' (a point on a photo: x and y) or 'control'."""

    stage: int
    context: str  # "pair 1-2 (affine)", "strip 1, photo 3", "strip 2 control"
    what: str  # image | control | note
    point: str = ""
    photo: str = ""
    action: str = "removed"  # removed | suspended | note
    statistic: str = ""  # w | tau | T/q
    value: float = float("nan")
    critical: float = float("nan")
    reason: str = ""

    def line(self) -> str:
        where = f"point {self.point}" + (f" on photo {self.photo}" if self.photo else "")
        stat = (f" ({self.statistic} = {self.value:.2f}, critical {self.critical:.2f})"
                if self.statistic else "")
        if self.what == "note":
            return f"[{STAGES[self.stage]}] {self.context}: {self.reason}"
        return (f"[{STAGES[self.stage]}] {self.context}: {self.action} {self.what} {where}"
                f"{stat}: {self.reason}")


@dataclass
class ScreeningLog:
    entries: list[Entry] = field(default_factory=list)

    def add(self, entry: Entry) -> Entry:
        self.entries.append(entry)
        return entry

    def note(self, stage: int, context: str, text: str) -> None:
        self.add(Entry(stage, context, "note", action="note", reason=text))

    def removed(self, what: str = "image", stage: int | None = None) -> list[Entry]:
        return [e for e in self.entries if e.what == what and e.action == "removed"
                and (stage is None or e.stage == stage)]

    def removed_image(self) -> set[tuple[str, str]]:
        """(photo, point) of every removed image point."""
        return {(e.photo, e.point) for e in self.removed("image")}

    def removed_control(self) -> set[str]:
        return {e.point for e in self.removed("control")}

    def table(self) -> pd.DataFrame:
        cols = list(Entry.__dataclass_fields__)
        df = pd.DataFrame([asdict(e) for e in self.entries], columns=cols)
        df.insert(1, "stage_name", [STAGES[s] for s in df["stage"]])
        return df

    def summary(self) -> str:
        lines = ["Screening", "=" * 60]
        for s in (1, 2, 3, 0, 4):
            img = self.removed("image", s)
            ctl = self.removed("control", s)
            if s in (0, 4) and not img and not ctl:
                continue
            lines.append(f"stage {s} ({STAGES[s]}): {len(img)} image point(s), "
                         f"{len(ctl)} control point(s) removed")
        lines += ["", *[e.line() for e in self.entries]]
        return "\n".join(lines)
