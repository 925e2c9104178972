"""The line language of `baarda online`: one interpreter for a measurement file and for lines
typed at the prompt.

    camera focal=152.0 sigma=5 qyy=2 qtie=1
                                            principal distance (mm), sigma of x'' (µm),
                                            q_yy/q_xx, q of x'' at tie points/q_xx
    model NAME [base=92.0] [ties=31,32,33]  start a model (the one on the instrument is accepted)
    ID x' y' x'' y''                        a point of the model (mm), until
    end                                     orient the model and print its QC
    remeasure ID x' y' x'' y''              replace a point of the model on the instrument, QC
    drop ID                                 leave a point out, QC again
    accept | discard                        accept the model on the instrument, or throw it away
    matrix                                  print Qvv P of the model on the instrument
    coords                                  print the strip coordinates
    help | quit
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from baarda.options import DEFAULT_QTIE, DEFAULT_QYY, DEFAULT_TESTS, TestOptions
from baarda.relative.model_report import model_report
from baarda.relative.session import OnlineSession

KEYWORDS = ("camera", "model", "end", "remeasure", "drop", "accept", "discard", "matrix",
            "coords", "help", "quit")


class LineError(ValueError):
    """A bad line: message and the field at fault (the caller adds file and line)."""

    def __init__(self, message: str, column: str | None = None):
        super().__init__(message)
        self.column = column


def parse_number(text: str, name: str, allow_missing: bool = False) -> float:
    """A finite number of a measurement line's field `name` ('-': NaN where
    `allow_missing`); a LineError naming the field otherwise."""
    if allow_missing and text == "-":
        return float("nan")
    try:
        v = float(text)
    except ValueError:
        raise LineError(f"{name} is not a number: {text!r}", name) from None
    if not np.isfinite(v):
        raise LineError(f"{name} is not finite: {text!r}", name)
    return v


def _numbers(fields: list[str], names: list[str]) -> list[float]:
    if len(fields) != len(names):
        raise LineError(f"expected {len(names)} numbers ({' '.join(names)}), got "
                        f"{len(fields)}")
    return [parse_number(f, n) for f, n in zip(fields, names, strict=True)]


def _options(fields: list[str], allowed: tuple[str, ...]) -> dict[str, str]:
    opts = {}
    for f in fields:
        key, eq, val = f.partition("=")
        if not eq or key not in allowed:
            raise LineError(f"unknown option {f!r} (allowed: "
                            f"{', '.join(a + '=' for a in allowed)})", key)
        opts[key] = val
    return opts


MEAS = ["x'", "y'", "x''", "y''"]


@dataclass
class Interpreter:
    """Feeds lines to an OnlineSession and writes what the operator sees through `say`."""

    say: Callable[[str], None]
    focal: float | None = None
    sigma: float = 10.0
    qyy: float = DEFAULT_QYY
    qtie: float = DEFAULT_QTIE
    tests: TestOptions = DEFAULT_TESTS
    statistic: str = "w"
    vce: bool = False  # variance components over the strip (OnlineSession(vce=True))
    session: OnlineSession | None = None
    collecting: dict | None = None  # model being typed: name, base, ties, points
    done: bool = False
    log: list[str] = field(default_factory=list)

    def feed(self, line: str) -> None:
        """Interpret one line; raises LineError, GeometryError or ValueError on bad input."""
        text = line.split("#", 1)[0].strip()
        if not text:
            return
        f = text.split()
        key = f[0].lower()
        if self.collecting is not None and key != "end":
            if key in KEYWORDS and key != "end":
                raise LineError(f"'{key}' inside model {self.collecting['name']}: close the "
                                "point list with 'end' first", "command")
            pid = f[0]
            if pid in self.collecting["points"]:
                raise LineError(f"point {pid} twice in model {self.collecting['name']}", "id")
            self.collecting["points"][pid] = tuple(_numbers(f[1:], MEAS))
            return
        getattr(self, f"_do_{key}", self._unknown)(f)

    def finish(self) -> None:
        """End of input: a model still being typed is an error, one on the instrument is
        accepted."""
        if self.collecting is not None:
            raise LineError(f"model {self.collecting['name']} has no 'end' line", "end")
        if self.session is not None and self.session.current is not None:
            self._accept()

    # -- commands ------------------------------------------------------------------------
    def _unknown(self, f: list[str]) -> None:
        raise LineError(f"unknown command {f[0]!r} (a point line belongs between 'model' and "
                        "'end'; commands: " + ", ".join(KEYWORDS) + ")", "command")

    def _do_camera(self, f: list[str]) -> None:
        if self.session is not None:
            raise LineError("'camera' must come before the first model", "camera")
        o = _options(f[1:], ("focal", "sigma", "qyy", "qtie"))
        for k, v in o.items():
            (val,) = _numbers([v], [k])
            if not val > 0:
                raise LineError(f"{k} must be positive", k)
            setattr(self, k, val)

    def _do_model(self, f: list[str]) -> None:
        if len(f) < 2:
            raise LineError("'model' needs a name", "name")
        o = _options(f[2:], ("base", "ties"))
        base = _numbers([o["base"]], ["base"])[0] if "base" in o else None
        ties = [t for t in o["ties"].split(",") if t] if "ties" in o else None
        if self.session is None:
            if self.focal is None:
                raise LineError("the principal distance is unknown: give a 'camera focal=...' "
                                "line or --focal", "focal")
            self.session = OnlineSession(self.focal, self.sigma, self.qyy, self.tests,
                                         self.statistic, base, self.qtie, vce=self.vce)
        elif base is not None:
            raise LineError("base= is for the first model only (later models take the scale "
                            "from their tie points)", "base")
        if self.session.current is not None:
            self._accept()
        self.collecting = {"name": f[1], "ties": ties, "points": {}}

    def _do_end(self, f: list[str]) -> None:
        if self.collecting is None:
            raise LineError("'end' without 'model'", "end")
        c, self.collecting = self.collecting, None
        assert self.session is not None  # created by model
        self._show(self.session.add_model(c["name"], c["points"], c["ties"]))

    def _do_remeasure(self, f: list[str]) -> None:
        if len(f) != 6:
            raise LineError("usage: remeasure ID x' y' x'' y''")
        self._need()
        self.say(f"remeasured point {f[1]}")
        assert self.session is not None  # _need
        self._show(self.session.remeasure(f[1], *_numbers(f[2:], MEAS)))

    def _do_drop(self, f: list[str]) -> None:
        if len(f) != 2:
            raise LineError("usage: drop ID")
        self._need()
        assert self.session is not None  # _need
        try:
            qc = self.session.drop(f[1])
        except KeyError as e:
            raise LineError(str(e.args[0]), "id") from None
        self.say(f"dropped point {f[1]}")
        self._show(qc)

    def _do_accept(self, f: list[str]) -> None:
        self._need()
        self._accept()

    def _do_discard(self, f: list[str]) -> None:
        self._need()
        assert self.session is not None and self.session.current is not None  # _need
        name = self.session.current.orientation.name
        self.session.discard()
        self.say(f"model {name} discarded")

    def _do_matrix(self, f: list[str]) -> None:
        self._need()
        assert self.session is not None  # _need
        self.say(matrix_text(self.session.current))

    def _do_coords(self, f: list[str]) -> None:
        self.say(coordinates_text(self.session))

    def _do_help(self, f: list[str]) -> None:
        self.say(__doc__.split("\n\n", 1)[1].rstrip())

    def _do_quit(self, f: list[str]) -> None:
        self.done = True

    def _need(self) -> None:
        if self.session is None or self.session.current is None:
            raise LineError("no model is on the instrument", "command")

    def _accept(self) -> None:
        assert self.session is not None  # _need
        acc = self.session.accept()
        self.say(f"model {acc.name} accepted: {len(self.session.coordinates)} points in the "
                 "strip")

    def _show(self, qc) -> None:
        self.say(model_report(qc))


def matrix_text(qc) -> str:
    """Qvv P with labels 'point component'; column j: effect of an error in observation j."""
    labels = [qc.label(i) for i in range(len(qc.qvvp))]
    lines = ["  Qvv P (column: error in; row: shows at)",
             "        " + "".join(f"{s:>7}" for s in labels)]
    lines += [f"  {s:>6}" + "".join(f"{v:7.3f}" for v in qc.qvvp[i])
              for i, s in enumerate(labels)]
    return "\n".join(lines)


def coordinates_text(session: OnlineSession | None) -> str:
    if session is None or not session.coordinates:
        return "no strip coordinates yet"
    lines = ["  POINT             X          Y          Z   (model units: mm at photo scale)"]
    for pid, xyz in session.coordinates.items():
        lines.append(f"  {pid:<8} {xyz[0]:10.4f} {xyz[1]:10.4f} {xyz[2]:10.4f}")
    return "\n".join(lines)


def coordinates_csv(session: OnlineSession) -> str:
    model_of: dict[str, str] = {}
    for m in session.accepted:
        for p in m.orientation.points:
            model_of.setdefault(p, m.name)
    rows = ["point,X,Y,Z,model"]
    rows += [f"{p},{x[0]:.6f},{x[1]:.6f},{x[2]:.6f},{model_of[p]}"
             for p, x in session.coordinates.items()]
    return "\n".join(rows) + "\n"

