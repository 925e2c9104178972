"""The line language of `baarda online --bundle PROJECT`: measurements on stdin, one answer
each (docs/online.md, "The growing bundle").

    point PHOTO POINT x y [sigma]       an image point (mm; sigma µm), tested at once
    photo PHOTO [camera=C] [strip=S] [eo=X0,Y0,Z0,omega,phi,kappa]
                                        a photo (new ones: orientation from eo=, angles in
                                        the project's unit, or by resection); its points
    POINT x y [sigma]                   follow, one a line, until
    end                                 test the photo's points together
    control POINT X Y Z [sX sY sZ]      control coordinates (m; '-' not observed)
    gnss PHOTO X Y Z [sX sY sZ]         the GNSS antenna position of a photo (m)
    remeasure PHOTO POINT x y [sigma]   replace an image point (removed, added, tested)
    remove point PHOTO POINT | remove control POINT | remove gnss PHOTO | remove photo PHOTO
    aside POINT                         take a point out until its next ray (the test cannot
                                        tell which of its rays is wrong; the next may)
    status                              the block now: photos, sigma0, rejected observations
    help | quit

`#` starts a comment.  Each measurement is answered in ANAPLOT's manner (answers.Answer.text)
or as one JSON object a line (`--json`, for a program that drives the measuring).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TypedDict

import numpy as np

from baarda.block.rotation import angle_to_rad
from baarda.io.project import SIGMA_GROUND_MAX_M
from baarda.kinds import GNSS
from baarda.online.answers import Answer
from baarda.online.bundle import OnlineBundle
from baarda.relative.online_commands import LineError, parse_number

HELP = __doc__.split("\n\n")[1]
#: the largest standard deviation of an image coordinate (µm), and the largest coordinate
#: (m): beyond them the statistics overflow and nothing is meant (of a ground coordinate:
#: SIGMA_GROUND_MAX_M, as in ground_points.csv)
SIGMA_IMAGE_MAX_UM, COORDINATE_MAX_M = 1e6, 1e9


def _numbers(fields: list[str], names: list[str], optional: Sequence[str] = (),
             allow_missing: bool = False, largest: float | None = None,
             sigma_max: float | None = None) -> list[float]:
    """The numbers of a line's fields `names` (then `optional`): the coordinates at most
    `largest` in size, the optional ones (standard deviations) positive and at most
    `sigma_max`; a LineError naming the field otherwise."""
    if not len(names) <= len(fields) <= len(names) + len(optional):
        want = " ".join(names) + "".join(f" [{o}]" for o in optional)
        raise LineError(f"expected {want}, got {len(fields)} value(s)")
    values = [parse_number(f, n, allow_missing) for f, n in
              zip(fields, list(names) + list(optional), strict=False)]
    for v, n in zip(values, names, strict=False):
        if largest is not None and abs(v) > largest:
            raise LineError(f"{n} is beyond {largest:g} in size: {v:.6g}", n)
    for v, n in zip(values[len(names):], optional, strict=False):
        if sigma_max is not None and not 0 < v <= sigma_max:
            raise LineError(f"{n} must be positive and at most {sigma_max:g}: {v:.6g}", n)
    return values


class Limits(TypedDict):
    """The bounds of a line's numbers (_numbers)."""

    largest: float
    sigma_max: float


IMAGE: Limits = {"largest": COORDINATE_MAX_M, "sigma_max": SIGMA_IMAGE_MAX_UM}  # mm, µm
GROUND: Limits = {"largest": COORDINATE_MAX_M, "sigma_max": SIGMA_GROUND_MAX_M}  # m


class BundleInterpreter:
    """Feeds the lines of the language to an OnlineBundle and says each answer (text, or a
    JSON line with `json`)."""

    def __init__(self, online: OnlineBundle, say: Callable[[str], None], *,
                 json: bool = False):
        self.ob, self.say, self.json = online, say, json
        self.done = False
        self.collecting: tuple[str, dict, dict] | None = None  # a photo's points until 'end'
        self.answers: list[Answer] = []
        if online.first is not None:
            self._tell(online.first)

    def _tell(self, a: Answer) -> None:
        self.answers.append(a)
        self.say(a.json() if self.json else a.text())

    def feed(self, line: str) -> None:
        text = line.split("#", 1)[0].strip()
        if not text:
            return
        fields = text.split()
        word = fields[0].lower()
        if self.collecting is not None and word not in KEYWORDS:
            x, y, *s = _numbers(fields[1:], ["x", "y"], ["sigma"], **IMAGE)
            self.collecting[1][fields[0]] = (x, y, *s)
            return
        if self.collecting is not None and word != "end":
            raise LineError(f"'{word}' inside photo {self.collecting[0]}: close its points "
                            "with 'end' first")
        COMMANDS.get(word, BundleInterpreter._unknown)(self, fields[1:], word)

    def finish(self) -> None:
        if self.collecting is not None:
            raise LineError(f"photo {self.collecting[0]} is not closed with 'end'")

    # ------------------------------------------------------------ commands
    def _unknown(self, fields, word) -> None:
        raise LineError(f"unknown command '{word}' (one of {', '.join(KEYWORDS)}, or "
                        "'help')", "command")

    def _point(self, fields, word) -> None:
        if len(fields) < 4:
            raise LineError("point PHOTO POINT x y [sigma]")
        x, y, *s = _numbers(fields[2:], ["x", "y"], ["sigma"], **IMAGE)
        self._tell(self.ob.add_image_point(fields[0], fields[1], x, y, *s))

    def _photo(self, fields, word) -> None:
        if not fields:
            raise LineError("photo PHOTO [camera=C] [strip=S] [eo=X0,Y0,Z0,omega,phi,kappa]")
        opts = {}
        for f in fields[1:]:
            key, sep, value = f.partition("=")
            if not sep or key not in ("camera", "strip", "eo"):
                raise LineError(f"unknown option {f!r} (camera=, strip=, eo=)", key)
            opts[key] = value
        if "eo" in opts:
            v = _numbers(opts["eo"].split(","), ["X0", "Y0", "Z0", "omega", "phi", "kappa"],
                         largest=COORDINATE_MAX_M)
            unit = self.ob.m.settings.angle_unit
            opts["eo"] = np.concatenate([v[:3], angle_to_rad(np.array(v[3:]), unit)])
        self.collecting = (fields[0], {}, opts)

    def _end(self, fields, word) -> None:
        if self.collecting is None:
            raise LineError("'end' without a photo")
        pid, points, opts = self.collecting
        self.collecting = None
        self._tell(self.ob.add_photo(pid, points, **opts))

    def _control(self, fields, word) -> None:
        if len(fields) not in (4, 7):
            raise LineError("control POINT X Y Z [sX sY sZ]")
        v = _numbers(fields[1:], ["X", "Y", "Z"], ["sX", "sY", "sZ"], allow_missing=True,
                     **GROUND)
        sig = np.array(v[3:] if len(v) == 6 else self.ob.m.settings.sigma_control_m, float)
        xyz = np.array(v[:3])
        self._tell(self.ob.add_control(fields[0], xyz, np.where(np.isfinite(xyz), sig,
                                                                np.nan)))

    def _gnss(self, fields, word) -> None:
        if len(fields) not in (4, 7):
            raise LineError("gnss PHOTO X Y Z [sX sY sZ]")
        v = _numbers(fields[1:], ["X", "Y", "Z"], ["sX", "sY", "sZ"], **GROUND)
        sig = v[3:] if len(v) == 6 else [self._gnss_sigma()] * 3
        self._tell(self.ob.add_gnss(fields[0], v[:3], sig))

    def _gnss_sigma(self) -> float:
        s = self.ob.m.g_sigma
        if not s:
            raise LineError("give the GNSS sigmas (sX sY sZ, m): the block has none to copy")
        return float(np.median(np.concatenate(s)))

    def _remeasure(self, fields, word) -> None:
        if len(fields) < 4:
            raise LineError("remeasure PHOTO POINT x y [sigma]")
        x, y, *s = _numbers(fields[2:], ["x", "y"], ["sigma"], **IMAGE)
        self.ob.remove_image_point(fields[0], fields[1])
        self._tell(self.ob.add_image_point(fields[0], fields[1], x, y, *s))

    def _remove(self, fields, word) -> None:
        what = fields[0].lower() if fields else ""
        args = fields[1:]
        if what == "point" and len(args) == 2:
            a = self.ob.remove_image_point(*args)
        elif what == "control" and len(args) == 1:
            a = self.ob.remove_control(args[0])
        elif what == GNSS.name and len(args) == 1:
            a = self.ob.remove_gnss(args[0])
        elif what == "photo" and len(args) == 1:
            a = self.ob.remove_photo(args[0])
        else:
            raise LineError("remove point PHOTO POINT | remove control POINT | remove gnss "
                            "PHOTO | remove photo PHOTO")
        self._tell(a)

    def _aside(self, fields, word) -> None:
        if len(fields) != 1:
            raise LineError("aside POINT")
        self._tell(self.ob.set_aside(fields[0]))

    def _status(self, fields, word) -> None:
        self.say(self.ob.status())

    def _help(self, fields, word) -> None:
        self.say(HELP)

    def _quit(self, fields, word) -> None:
        self.done = True


#: the commands of the language and their methods: the only words a line can dispatch to
#: (no attribute is looked up by a word of the input)
COMMANDS: dict[str, Callable[[BundleInterpreter, list[str], str], None]] = {
    "point": BundleInterpreter._point, "photo": BundleInterpreter._photo,
    "end": BundleInterpreter._end, "control": BundleInterpreter._control,
    GNSS.name: BundleInterpreter._gnss, "remeasure": BundleInterpreter._remeasure,
    "remove": BundleInterpreter._remove, "aside": BundleInterpreter._aside,
    "status": BundleInterpreter._status, "help": BundleInterpreter._help,
    "quit": BundleInterpreter._quit}
KEYWORDS = tuple(COMMANDS)  # the words of the language, in the order help names them
