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
    if p.is_dir():
        from baarda.io.project import FILES

        has = [f for f in FILES[1:] if (p / f).is_file()]
        if has:
            raise ProjectError(str(p / "project.toml"), "not found: the folder has "
                               f"{', '.join(has)} but a native project needs project.toml "
                               "beside them (docs/format.md)")
        raise ProjectError(str(p), "format not recognised: no project.toml (a native project "
                           "folder), and not a COLMAP model, AICON project, MicMac/IGN folder, "
                           "OpenSfM dataset or ODM project folder")
    raise ProjectError(str(p), "format not recognised (native project folder, COLMAP model, "
                       "AICON project, DBAT script .xml, PhotoModeler export .txt, BAL file, "
                       "MicMac/IGN folder, OpenSfM dataset or ODM project)")


# what each format's path is: a file, a folder, or either (AICON: the folder or one of its
# files; OpenSfM: the dataset folder or an ODM project)
FILE_FORMATS = {"dbat": "a DBAT script .xml", "photomodeler": "a PhotoModeler export .txt",
                "bal": "a BAL file (.txt or .bz2)"}
FOLDER_FORMATS = {"project": "a native project folder (project.toml and its CSV files)",
                  "colmap": "a COLMAP model folder", "micmac": "a MicMac/IGN folder",
                  "opensfm": "an OpenSfM dataset or ODM project folder"}


def _check_kind(p: Path, fmt: str) -> None:
    """ProjectError when --format names a format whose input is a file and the path is a
    folder, or the other way round (the reader would say 'file not found')."""
    if not p.exists():
        raise ProjectError(str(p), "not found")
    wrong = (fmt in FILE_FORMATS and p.is_dir()) or (fmt in FOLDER_FORMATS and p.is_file())
    if not wrong:
        return
    try:
        found = f"; it looks like {detect(p)} input (leave out --format)"
    except ProjectError:
        found = ""
    want = FILE_FORMATS.get(fmt) or FOLDER_FORMATS[fmt]
    kind = "a folder" if p.is_dir() else "a file"
    raise ProjectError(str(p), f"--format {fmt} reads {want}, but this is {kind}{found}")


def read_any(path: str | Path, fmt: str | None = None, *, pixel_mm: float | None = None,
             sigma_px: float | None = None, sigma_image_um: float | None = None,
             encoding: str = ENCODING, camera: str | Path | None = None,
             crs: str | None = None) -> Block:
    """Read any supported input into a Block.

    pixel_mm, sigma_px, sigma_image_um: pixel size [mm] and image sigma [px] or [µm],
    resolved for the format by io/image_sigma.py (an option that does not apply to it is
    an error; None: the format's own); encoding: of the text files of a project, AICON or
    PhotoModeler input (COLMAP and BAL are UTF-8 / ASCII by definition, DBAT's XML names
    its own); camera: a DBAT camera file (a calibration result) replacing a DBAT script's
    camera; crs: the project CRS of an OpenSfM dataset (its topocentric frame is placed in
    it; other formats take the CRS in pipeline.read).  The cameras are as the files give
    them: pipeline.read applies the calibration group (settings.calibration_group).
    """
    from baarda.io.image_sigma import check_image_sigmas, resolve_image_options, with_image_sigma

    p = Path(path)
    if fmt is not None and fmt not in FORMATS:
        raise ProjectError(str(p), f"unknown format '{fmt}' (one of {', '.join(FORMATS)})")
    if fmt is not None:
        _check_kind(p, fmt)
    fmt = fmt or detect(p)
    if camera is not None and fmt != "dbat":
        raise ProjectError(str(camera), f"a camera file replaces the camera of a DBAT script; "
                           f"{p.name} is {fmt} input (give its cameras in its own files)")
    opts = resolve_image_options(fmt, pixel_mm, sigma_px, sigma_image_um)
    if fmt == "project":
        from baarda.io.project import read_project

        block = read_project(p, encoding)
    else:
        block = _read(p, fmt, opts.pixel_mm, opts.sigma_px, encoding, camera, crs)
    check_image_sigmas(block)
    return block if opts.sigma_um is None else with_image_sigma(block, opts.sigma_um)


def _read(p: Path, fmt: str, pixel_mm: float | None, sigma_px: float | None, encoding: str,
          camera: str | Path | None, crs: str | None) -> Block:
    """The reader of `fmt` (the image options resolved: read_any)."""
    if fmt == "colmap":
        from baarda.io.colmap_block import read_colmap_block

        folder = _colmap_folder(p) or p
        return read_colmap_block(folder, pixel_mm=pixel_mm, sigma_px=sigma_px,
                                 name=p.name)
    if fmt == "aicon":
        from baarda.io.aicon import read_aicon

        return read_aicon(p, encoding).to_block()
    if fmt == "dbat":
        from baarda.io.dbat import read_dbat

        return read_dbat(p, camera=camera, sigma_px=sigma_px)
    if fmt == "photomodeler":
        from baarda.io.photomodeler import read_photomodeler

        return read_photomodeler(p, encoding, pixel_mm=pixel_mm, sigma_px=sigma_px)
    if fmt == "micmac":
        from baarda.io.micmac import IMAGE_SIGMA_PX, read_micmac

        return read_micmac(p, image_sigma_px=IMAGE_SIGMA_PX if sigma_px is None else sigma_px)
    if fmt == "opensfm":
        from baarda.io.opensfm import read_opensfm

        assert pixel_mm is not None and sigma_px is not None  # image_options: a pixel format
        return read_opensfm(p, pixel_mm=pixel_mm, sigma_px=sigma_px, crs=crs)
    from baarda.io.bal import read_bal_block

    return read_bal_block(p, pixel_mm=pixel_mm, sigma_px=sigma_px)
