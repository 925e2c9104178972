"""OpenDroneMap's gcp_list.txt (docs.opendronemap.org/gcp.html), read for `--gcp-list FILE`:

    <CRS>                      a PROJ string, EPSG:NNNN or 'WGS84 UTM <zone>[N|S]'
    geo_x geo_y geo_z im_x im_y image_name [gcp_name] [extra ...]

Fields separated by tabs or spaces; blank lines and lines starting with '#' are skipped (a
'#' line before the CRS line too); geo_z may be NaN (no height: a planimetric GCP); im_x,
im_y are pixels of the original image from its upper-left corner, x right, y down, the first
pixel's centre at (0, 0) (as OpenSfM reads them).  A GCP is named by its 7th field; without
one, by its coordinates (ODM tells GCPs apart by them): 'x_y_z' as written.  Extra fields
are ignored.  Bad input is an error naming the file, the line and the field: fewer than six
fields, a number that is not one, one GCP name with two sets of coordinates.  (An image
that is not a photo of the block and a GCP measured twice on one image are named by
block/gcp.py, which knows the block.)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from baarda.block.gcp import GcpList
from baarda.errors import ProjectError
from baarda.io.records import parse_number
from baarda.io.text_files import ENCODING, decode_text, file_bytes, split_lines

FIELDS = "geo_x geo_y geo_z im_x im_y image_name [gcp_name]"


def parse_crs_line(text: str) -> str:
    """The CRS of gcp_list.txt's first line: ODM's 'WGS84 UTM 32N' as 'EPSG:32632', an
    EPSG code or a PROJ string as written (pyproj checks it later)."""
    import re

    t = text.strip()
    m = re.fullmatch(r"WGS84\s+UTM\s+(\d{1,2})\s*([NS])", t, re.IGNORECASE)
    if m and 1 <= int(m.group(1)) <= 60:
        return f"EPSG:{(32600 if m.group(2).upper() == 'N' else 32700) + int(m.group(1))}"
    return t


def read_gcp_list(path: str | Path, encoding: str = ENCODING) -> GcpList:
    """A gcp_list.txt (module docstring); ProjectError naming file, line and field."""
    spath = str(path)
    lines = split_lines(decode_text(file_bytes(path, "GCP list not found"), spath, encoding))
    rows = [(n, s.strip()) for n, s in enumerate(lines, start=1)
            if s.strip() and not s.lstrip().startswith("#")]
    if not rows:
        raise ProjectError(spath, f"empty: the first line names the CRS, then lines '{FIELDS}'")
    crs_line, crs_text = rows[0]
    if len(rows) == 1:
        raise ProjectError(spath, f"no GCP measurements after the CRS line (lines '{FIELDS}')",
                           crs_line + 1)
    ids: list[str] = []
    index: dict[str, int] = {}
    xyz: list[np.ndarray] = []
    first: list[int] = []
    gcp, image, uv, at = [], [], [], []
    for n, s in rows[1:]:
        f = s.split()
        if len(f) < 6:
            raise ProjectError(spath, f"expected '{FIELDS}' separated by tabs or spaces, found "
                               f"{len(f)} field(s)", n, FIELDS.split()[len(f)])
        x = parse_number(f[0], spath, n, "geo_x")
        y = parse_number(f[1], spath, n, "geo_y")
        z = np.nan if f[2].lower() == "nan" else parse_number(f[2], spath, n, "geo_z")
        u = parse_number(f[3], spath, n, "im_x")
        v = parse_number(f[4], spath, n, "im_y")
        name = f[6] if len(f) > 6 else f"{f[0]}_{f[1]}_{f[2]}"
        c = np.array([x, y, z])
        k = index.get(name)
        if k is None:
            k = index[name] = len(ids)
            ids.append(name)
            xyz.append(c)
            first.append(n)
        elif not np.allclose(xyz[k], c, rtol=0, atol=1e-9, equal_nan=True):
            raise ProjectError(spath, f"GCP {name} has other coordinates on line {first[k]} "
                               f"({', '.join(f'{t:.10g}' for t in xyz[k])})", n, "geo_x")
        gcp.append(k)
        image.append(f[5])
        uv.append((u, v))
        at.append(n)
    return GcpList(spath, parse_crs_line(crs_text), crs_line, ids, np.array(xyz, float),
                   np.array(first, np.int64), np.array(gcp, np.int64), image,
                   np.array(uv, float).reshape(-1, 2), np.array(at, np.int64))


def image_sizes(names: list[str], folders: list[Path]) -> dict[str, tuple[int, int]]:
    """(width, height) [px] of the image files `names` (their base names) found in the first
    of `folders` that holds them (Pillow reads the header only); names not found are left
    out."""
    from PIL import Image, UnidentifiedImageError

    out: dict[str, tuple[int, int]] = {}
    for name in dict.fromkeys(names):
        for folder in folders:
            p = folder / Path(name).name
            if p.is_file():
                try:
                    with Image.open(p) as im:
                        out[name] = (int(im.width), int(im.height))
                except (OSError, UnidentifiedImageError):
                    continue
                break
    return out
