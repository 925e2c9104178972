"""Recognise an input by what the path is and read it into a Block (`read_any`).

| what the path is | format | reader |
|---|---|---|
| folder with project.toml | native project | io/project.py |
| folder with cameras, images, points3D (.txt/.bin), or sparse/, sparse/0/ | COLMAP | colmap |
| folder or file of an AICON project (.ior .eor .obc .phc [.scale]) | AICON | io/aicon.py |
| .xml with ``dbat_script_version`` | DBAT script | io/dbat.py |
| .txt starting with "Bundle Soln" | PhotoModeler export | io/photomodeler.py |
| .bz2 / text whose first line is three counts | BAL | io/bal.py |
| folder of MicMac tie points .mes, orientations .opk, IGN camera .xml | MicMac | micmac |
| OpenSfM dataset (reconstruction.json, tracks.csv) or ODM project (opensfm/) | OpenSfM | opensfm |
"""

from __future__ import annotations

from pathlib import Path

from baarda.block.photo_block import Block
from baarda.errors import ProjectError
from baarda.io.records import ENCODING

# Each reader is imported when its format is asked about, so that a command that meets a
# bad file early has not paid for the imports of every reader (numba for COLMAP, pandas for
# native projects): issue 19, a hostile file costs what the interpreter costs.

FORMATS = ("project", "colmap", "aicon", "dbat", "photomodeler", "bal", "micmac", "opensfm")


def _colmap_folder(p: Path) -> Path | None:
    from baarda.io.colmap import is_colmap_model

    for cand in (p, p / "sparse", p / "sparse" / "0"):
        if is_colmap_model(cand):
            return cand
    return None


def detect(path: str | Path) -> str:
    """The format of `path` (one of FORMATS); ProjectError if none fits."""
    p = Path(path)
    if not p.exists():
        raise ProjectError(str(p), "not found")
    if p.is_dir() and (p / "project.toml").is_file():
        return "project"
    if p.is_dir() and _colmap_folder(p) is not None:
        return "colmap"
    from baarda.io.aicon import is_aicon
    from baarda.io.micmac import is_micmac

    if is_aicon(p):
        return "aicon"
    if is_micmac(p):
        return "micmac"
    from baarda.io.opensfm import is_opensfm

    if is_opensfm(p):
        return "opensfm"
    if p.is_file():
        from baarda.io.bal import is_bal
        from baarda.io.dbat import is_dbat_script
        from baarda.io.photomodeler import is_photomodeler_export

        if is_dbat_script(p):
            return "dbat"
        if is_photomodeler_export(p):
            return "photomodeler"
        if is_bal(p):
            return "bal"
    raise ProjectError(str(p), "format not recognised (native project folder, COLMAP model, "
                       "AICON project, DBAT script .xml, PhotoModeler export .txt, BAL file, "
                       "MicMac/IGN folder, OpenSfM dataset or ODM project)")


def read_any(path: str | Path, fmt: str | None = None, *, pixel_mm: float = 0.001,
             sigma_px: float = 1.0, sigma_image_mm: float | None = None,
             encoding: str = ENCODING, camera: str | Path | None = None,
             crs: str | None = None) -> Block:
    """Read any supported input into a Block.

    pixel_mm, sigma_px: nominal pixel size and image sigma for formats without a physical
    pixel size (COLMAP, BAL, OpenSfM); sigma_image_mm: image sigma for AICON (default: the file's);
    encoding: of the text files of a project, AICON or PhotoModeler input (COLMAP and BAL
    are UTF-8 / ASCII by definition, DBAT's XML names its own); camera: a DBAT camera file
    (a calibration result) replacing a DBAT script's camera; crs: the project CRS of an
    OpenSfM dataset (its topocentric frame is placed in it; other formats take the CRS in
    pipeline.read).
    """
    p = Path(path)
    fmt = fmt or detect(p)
    if fmt not in FORMATS:
        raise ProjectError(str(p), f"unknown format '{fmt}' (one of {', '.join(FORMATS)})")
    if camera is not None and fmt != "dbat":
        raise ProjectError(str(camera), f"a camera file replaces the camera of a DBAT script; "
                           f"{p.name} is {fmt} input (give its cameras in its own files)")
    if fmt == "project":
        from baarda.io.project import read_project

        return read_project(p, encoding)
    if fmt == "colmap":
        from baarda.io.colmap_block import read_colmap_block

        folder = _colmap_folder(p) or p
        return read_colmap_block(folder, pixel_mm=pixel_mm, sigma_px=sigma_px,
                                 name=p.name)
    if fmt == "aicon":
        from baarda.io.aicon import read_aicon

        return read_aicon(p, encoding).to_block(sigma_image_mm=sigma_image_mm)
    if fmt == "dbat":
        from baarda.io.dbat import read_dbat

        return read_dbat(p, camera=camera)
    if fmt == "photomodeler":
        from baarda.io.photomodeler import read_photomodeler

        return read_photomodeler(p, encoding)
    if fmt == "micmac":
        from baarda.io.micmac import read_micmac

        return read_micmac(p)
    if fmt == "opensfm":
        from baarda.io.opensfm import read_opensfm

        return read_opensfm(p, pixel_mm=pixel_mm, sigma_px=sigma_px, crs=crs)
    from baarda.io.bal import read_bal_block

    return read_bal_block(p, pixel_mm=pixel_mm, sigma_px=sigma_px)
