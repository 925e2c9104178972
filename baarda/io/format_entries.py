"""The uniform entry points of the readers written before the format registry
(io/formats.py): `detect_X(path) -> bool` and `read_X(path, request) -> Block` for each, so
that the registry calls every reader the same way.  A new reader needs none of this: its
own module has the two functions and the registry names them.

Each imports its reader when called: recognising or reading one format costs that reader's
imports only (issue 19).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from baarda.block.photo_block import Block
    from baarda.io.formats import ReadRequest


def detect_project(p: Path) -> bool:
    return p.is_dir() and (p / "project.toml").is_file()


def read_project(p: Path, r: ReadRequest) -> Block:
    from baarda.io.project import read_project as read

    return read(p, r.encoding)


def colmap_folder(p: Path) -> Path | None:
    """The COLMAP model folder of `p`: itself, sparse/ or sparse/0/ (None: none)."""
    from baarda.io.colmap import is_colmap_model

    for cand in (p, p / "sparse", p / "sparse" / "0"):
        if is_colmap_model(cand):
            return cand
    return None


def detect_colmap(p: Path) -> bool:
    return p.is_dir() and colmap_folder(p) is not None


def read_colmap(p: Path, r: ReadRequest) -> Block:
    from baarda.io.colmap_block import read_colmap_block

    return read_colmap_block(colmap_folder(p) or p, pixel_mm=r.pixel_mm, sigma_px=r.sigma_px,
                             name=p.name)


def detect_aicon(p: Path) -> bool:
    from baarda.io.aicon import is_aicon

    return is_aicon(p)


def read_aicon(p: Path, r: ReadRequest) -> Block:
    from baarda.io.aicon import read_aicon as read

    return read(p, r.encoding).to_block()


def detect_micmac(p: Path) -> bool:
    from baarda.io.micmac import is_micmac

    return is_micmac(p)


def read_micmac(p: Path, r: ReadRequest) -> Block:
    from baarda.io.micmac import IMAGE_SIGMA_PX
    from baarda.io.micmac import read_micmac as read

    return read(p, image_sigma_px=IMAGE_SIGMA_PX if r.sigma_px is None else r.sigma_px)


def detect_opensfm(p: Path) -> bool:
    from baarda.io.opensfm import is_opensfm

    return is_opensfm(p)


def read_opensfm(p: Path, r: ReadRequest) -> Block:
    from baarda.io.image_sigma import PIXEL_MM, SIGMA_PX
    from baarda.io.opensfm import read_opensfm as read

    return read(p, pixel_mm=PIXEL_MM if r.pixel_mm is None else r.pixel_mm,
                sigma_px=SIGMA_PX if r.sigma_px is None else r.sigma_px, crs=r.crs)


def detect_dbat(p: Path) -> bool:
    from baarda.io.dbat import is_dbat_script

    return is_dbat_script(p)


def read_dbat(p: Path, r: ReadRequest) -> Block:
    from baarda.io.dbat import read_dbat as read

    return read(p, camera=r.camera, sigma_px=r.sigma_px)


def detect_photomodeler(p: Path) -> bool:
    from baarda.io.photomodeler import is_photomodeler_export

    return is_photomodeler_export(p)


def read_photomodeler(p: Path, r: ReadRequest) -> Block:
    from baarda.io.photomodeler import read_photomodeler as read

    return read(p, r.encoding, pixel_mm=r.pixel_mm, sigma_px=r.sigma_px)


def detect_bal(p: Path) -> bool:
    from baarda.io.bal import is_bal

    return is_bal(p)


def read_bal(p: Path, r: ReadRequest) -> Block:
    from baarda.io.bal import read_bal_block

    return read_bal_block(p, pixel_mm=r.pixel_mm, sigma_px=r.sigma_px)
