"""The bundle protocol of AICON 3D Studio (HTML, German: "Protokoll
Buendelblockausgleichung"), read for what the AICON adjustment was set up with:

* the camera parameters it estimated ("Innere Orientierungen": a parameter with a standard
  deviation was estimated, one marked "fest" was held), with their values and standard
  deviations;
* the a-priori standard deviations of every image coordinate ("Bildkoordinaten": sx, sy a
  priori), which the project's .phc file does not carry (README of the JAiCov example);
* the protocol's own results per image coordinate (residuals vx, vy, redundancy numbers
  rx, ry and the two test values), for comparisons.

Names map to baarda's parameters: Ck -> c (c = -Ck), Xh -> x0, Yh -> y0, A1..A3, B1, B2,
C1, C2 -> a1..a3, b1, b2, c1, c2 of the `aicon` camera model.
"""

from __future__ import annotations

import html
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from baarda.errors import ProjectError
from baarda.io.image_sigma import SIGMA_IMAGE_UM

NAMES = {"Ck": "c", "Xh": "x0", "Yh": "y0", "A1": "a1", "A2": "a2", "A3": "a3", "B1": "b1",
         "B2": "b2", "C1": "c1", "C2": "c2"}
MAX_BYTES = 64 * 2**20
_NUMBER = r"[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?"
_ROW = re.compile(rf"^\s*(\S+)\s+(\d+)\s+({_NUMBER})\s+({_NUMBER})\s+({_NUMBER})\s+({_NUMBER})"
                  rf"\s+({_NUMBER})\s+({_NUMBER})\s+({_NUMBER})\s+({_NUMBER})\s+({_NUMBER})"
                  rf"\s+({_NUMBER})\s*$")


@dataclass(frozen=True)
class AiconProtocol:
    path: Path
    camera: dict[str, tuple[float, float | None]]  # baarda name -> (value, std or None: held)
    observations: dict[str, np.ndarray]  # point, image, x, y, vx, vy, sx, sy, rx, ry, t1, t2

    @property
    def free(self) -> tuple[str, ...]:
        """The camera parameters AICON estimated (baarda's names)."""
        return tuple(n for n, (_, s) in self.camera.items() if s is not None)


def _text(path: Path) -> str:
    data = path.read_bytes()
    if len(data) > MAX_BYTES:
        raise ProjectError(str(path), f"larger than {MAX_BYTES // 2**20} MB: not an AICON "
                           "protocol")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    if not re.search(r"</html>\s*$", text[-4096:], re.IGNORECASE):
        raise ProjectError(str(path), "the protocol does not end with </html>: the file is cut "
                           "short", text.count("\n") + 1)
    return html.unescape(re.sub(r"<[^>]*>", " ", text))


def read_protocol(path: str | Path) -> AiconProtocol:
    """Read the camera set-up and the image-coordinate table of an AICON protocol."""
    path = Path(path)
    text = _text(path)
    start = text.find("Innere Orientierungen ***")
    if start < 0:
        raise ProjectError(str(path), "no '*** Innere Orientierungen ***' section: not an AICON "
                           "bundle protocol")
    camera: dict[str, tuple[float, float | None]] = {}
    for line in text[start:start + 5000].splitlines():
        m = re.match(rf"^\s*(\w+)\s*:\s*({_NUMBER})\s+(fest|{_NUMBER})\s*$", line)
        if m and m.group(1) in NAMES:
            value = float(m.group(2))
            std = None if m.group(3) == "fest" else float(m.group(3))
            name = NAMES[m.group(1)]
            camera[name] = (-value if name == "c" else value, std)
        if line.strip().startswith("Korrelation"):
            break
    if not camera:
        raise ProjectError(str(path), "no camera parameters in 'Innere Orientierungen'")
    cols: dict[str, list] = {k: [] for k in ("point", "image", "x", "y", "vx", "vy", "sx", "sy",
                                             "rx", "ry", "t1", "t2")}
    table = text.find("Bildkoordinaten ***")
    low, high = (v * 1e-3 for v in SIGMA_IMAGE_UM)  # µm -> mm
    if table >= 0:
        first = text.count("\n", 0, table) + 1  # the line of the table's title
        for no, line in enumerate(text[table:].splitlines()[2:], start=first + 2):
            m = _ROW.match(line)
            if m is None:
                if line.strip().startswith("***"):
                    break
                continue
            cols["point"].append(m.group(1))
            cols["image"].append(int(m.group(2)))
            for k, name in enumerate(("x", "y", "vx", "vy", "sx", "sy", "rx", "ry", "t1", "t2")):
                cols[name].append(float(m.group(3 + k)))
            for name in ("sx", "sy"):
                if not low <= cols[name][-1] <= high:
                    raise ProjectError(str(path), f"standard deviation {cols[name][-1]:g} mm: "
                                       f"expected {low:g} to {high:g} mm", no, name)
    obs = {k: np.array(v, dtype=object if k == "point" else float) for k, v in cols.items()}
    obs["image"] = obs["image"].astype(np.int64)
    return AiconProtocol(path, camera, obs)
