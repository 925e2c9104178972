"""The format registry: one `FormatSpec` per reader; `detect` recognises an input by what
its path is, `read_any` reads it into a Block.  The `--format` choices, the help texts that
list the formats and the errors that name them are generated from the registry.

| what the path is | format | reader |
|---|---|---|
| folder with project.toml | native project | io/project.py |
| folder with cameras, images, points3D (.txt/.bin), or sparse/, sparse/0/ | COLMAP | colmap |
| folder or file of an AICON project (.ior .eor .obc .phc [.scale]) | AICON | io/aicon.py |
| folder of MicMac tie points .mes, orientations .opk, IGN camera .xml | MicMac | micmac |
| OpenSfM dataset (reconstruction.json, tracks.csv) or ODM project (opensfm/) | OpenSfM | opensfm |
| .xml with ``dbat_script_version`` | DBAT script | io/dbat.py |
| .txt starting with "Bundle Soln" | PhotoModeler export | io/photomodeler.py |
| .bz2 / text whose first line is three counts | BAL | io/bal.py |
| file (or folder's bundle.out) starting "# Bundle file v" | Bundler | io/bundler.py |
| file starting NVM_V3 | VisualSFM NVM | io/nvm.py |
| .psz zip with doc.xml, .psx | Metashape / PhotoScan project | io/metashape_project.py |
| .xml with <document> and <chunk> | Metashape cameras XML | io/metashape_cameras.py |
| .im file (or folder with one; by name: its content is checked when read) | PAT-B | io/patb.py |
| *bingo.txt (or folder with one; by name, as PAT-B) | BINGO + Pix4D | io/bingo.py |

A new reader is one module with `detect(path) -> bool` and `read(path, request) -> Block`
(`request`: a `ReadRequest`) and one `FormatSpec` line in REGISTRY (or `register`); the
functions are named "module:function" and imported when the format is asked about, so that
`baarda --help` and a command that meets a bad file early have not paid for the imports of
every reader (numba for COLMAP, pandas for native projects; issue 19).  Detection tries the
formats in the registry's order.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from baarda.errors import ProjectError
from baarda.io.text_files import ENCODING

if TYPE_CHECKING:  # the registry is read by `baarda --help`: no numpy, no reader
    from baarda.block.photo_block import Block


PATH_KINDS = ("file", "folder", "either")
# how a format's image coordinates relate to pixels (io/image_sigma.py):
#   nominal: pixels without a physical size (a nominal one, --pixel-mm, default 1 µm)
#   camera:  the pixel size of the file's camera (--pixel-mm refused)
#   header:  the pixel size from the file's header where it has one (else --pixel-mm)
#   mm:      image coordinates in mm, no pixels (--pixel-mm only converts --sigma-px)
PIXEL_POLICIES = ("nominal", "camera", "header", "mm")


@dataclass(frozen=True)
class ReadRequest:
    """What every reader may be given: the pixel size [mm] and the image sigma [px]
    resolved for its format (io/image_sigma.py; None: the format's own), the text encoding,
    a camera file replacing the input's camera (DBAT), the project CRS (OpenSfM), the model
    of a file with several (NVM)."""

    pixel_mm: float | None = None
    sigma_px: float | None = None
    encoding: str = ENCODING
    camera: Path | None = None
    crs: str | None = None
    model: int | None = None  # the model of a file with several (NVM; None: the first)
    tie_points: Path | None = None  # a Bundler file joining a Metashape cameras XML


Detect = Callable[[Path], bool]
Read = Callable[[Path, ReadRequest], "Block"]


@dataclass(frozen=True)
class FormatSpec:
    """One input format: its `--format` name, its title in messages ("COLMAP"), what its
    path is (`input`, e.g. "a COLMAP model folder"; `path` one of PATH_KINDS), its pixel
    policy (PIXEL_POLICIES), `detect` and `read` ("module:function" imported on demand, or
    the functions themselves), `writer` ("module:function" of the writer in baarda/output,
    None: baarda does not write it), `camera_file`: it takes --camera, `models`: a file may
    hold several models (--model K picks one), `tie_points`: it takes --tie-points,
    `control`: its files hold control and check
    points with their given coordinates (a result folder written in it keeps those, not the
    adjusted ones)."""

    name: str
    title: str
    input: str
    path: str
    pixels: str
    detect: str | Detect
    read: str | Read
    writer: str | None = None
    camera_file: bool = False
    models: bool = False
    tie_points: bool = False
    control: bool = False

    def __post_init__(self) -> None:
        if self.path not in PATH_KINDS or self.pixels not in PIXEL_POLICIES:
            raise ValueError(f"format {self.name}: path one of {PATH_KINDS}, pixels one of "
                             f"{PIXEL_POLICIES}")

    def detects(self, p: Path) -> bool:
        """Whether `p` is input of this format (False for a path of the wrong kind)."""
        if (self.path == "file" and not p.is_file()) or \
                (self.path == "folder" and not p.is_dir()):
            return False
        return bool(_function(self.detect)(p))

    def reads(self, p: Path, request: ReadRequest) -> Block:
        return _function(self.read)(p, request)

    def writes(self, block: Block, folder: Path) -> list[str]:
        """Write `block` into `folder` with this format's writer; its notes on what was
        dropped (ValueError when baarda does not write the format)."""
        if self.writer is None:
            raise ValueError(f"baarda does not write {self.title}")
        return _function(self.writer)(block, folder)


def _function(ref):
    """The function of a "module:function" reference (imported now), or `ref` itself."""
    if callable(ref):
        return ref
    module, name = ref.split(":")
    return getattr(importlib.import_module(module), name)


_E = "baarda.io.format_entries"
REGISTRY: list[FormatSpec] = [
    FormatSpec("project", "a native project",
               "a native project folder (project.toml and its CSV files)", "folder", "mm",
               f"{_E}:detect_project", f"{_E}:read_project",
               "baarda.output.project_files:write_project", control=True),
    FormatSpec("colmap", "COLMAP", "a COLMAP model folder", "folder", "nominal",
               f"{_E}:detect_colmap", f"{_E}:read_colmap",
               "baarda.output.block_formats:write_colmap_block"),
    FormatSpec("aicon", "AICON", "an AICON project (.ior .eor .obc .phc) or one of its files",
               "either", "mm", f"{_E}:detect_aicon", f"{_E}:read_aicon",
               "baarda.output.block_formats:write_aicon_block"),
    FormatSpec("micmac", "MicMac", "a MicMac/IGN folder", "folder", "camera",
               f"{_E}:detect_micmac", f"{_E}:read_micmac"),
    FormatSpec("opensfm", "OpenSfM", "an OpenSfM dataset or ODM project folder", "folder",
               "nominal", f"{_E}:detect_opensfm", f"{_E}:read_opensfm",
               "baarda.output.block_formats:write_opensfm_block",
               control=True),
    FormatSpec("dbat", "DBAT script", "a DBAT script .xml", "file", "camera",
               f"{_E}:detect_dbat", f"{_E}:read_dbat", camera_file=True),
    FormatSpec("photomodeler", "PhotoModeler", "a PhotoModeler export .txt", "file", "header",
               f"{_E}:detect_photomodeler", f"{_E}:read_photomodeler"),
    FormatSpec("bal", "BAL", "a BAL file (.txt or .bz2)", "file", "nominal",
               f"{_E}:detect_bal", f"{_E}:read_bal",
               "baarda.output.block_formats:write_bal_block"),
    FormatSpec("bundler", "Bundler", "a Bundler v0.3 bundle.out (list.txt beside it) or its "
               "folder", "either", "nominal", "baarda.io.bundler:detect",
               "baarda.io.bundler:read", "baarda.output.sfm_files:write_bundler"),
    FormatSpec("nvm", "VisualSFM NVM", "a VisualSFM NVM_V3 .nvm file", "file", "nominal",
               "baarda.io.nvm:detect", "baarda.io.nvm:read", "baarda.output.sfm_files:write_nvm",
               models=True),
    FormatSpec("metashape", "Agisoft Metashape", "a Metashape / PhotoScan project (.psz, "
               ".psx)", "file", "header", "baarda.io.metashape_project:detect",
               "baarda.io.metashape_project:read"),
    FormatSpec("metashape-xml", "Metashape cameras XML", "a Metashape cameras XML (File > "
               "Export > Cameras)", "file", "header", "baarda.io.metashape_cameras:detect",
               "baarda.io.metashape_cameras:read", "baarda.output.metashape_files:"
               "write_metashape", tie_points=True, control=True),
    FormatSpec("patb", "PAT-B", "a PAT-B .im file (.con .ori .at .pro beside it) or its folder",
               "either", "mm", "baarda.io.patb:detect", "baarda.io.patb:read",
               "baarda.output.patb_files:write_patb", control=True),
    FormatSpec("bingo", "BINGO", "a BINGO *bingo.txt (Pix4D's *_calibrated_camera_parameters"
               ".txt beside it) or its folder", "either", "header", "baarda.io.bingo:detect",
               "baarda.io.bingo:read", "baarda.output.bingo_files:write_bingo"),
]

FORMATS = tuple(s.name for s in REGISTRY)  # the built-in formats (format_names: all)


def register(spec: FormatSpec) -> None:
    """Add a format to the registry (detected after the earlier ones); ValueError when its
    name is taken."""
    if spec.name in format_names():
        raise ValueError(f"format '{spec.name}' is registered already")
    REGISTRY.append(spec)


def unregister(name: str) -> None:
    """Remove a format added by `register`."""
    REGISTRY[:] = [s for s in REGISTRY if s.name != name]


def format_names() -> tuple[str, ...]:
    return tuple(s.name for s in REGISTRY)


def spec(name: str) -> FormatSpec:
    """The FormatSpec of `name`; ValueError naming the formats when there is none."""
    for s in REGISTRY:
        if s.name == name:
            return s
    raise ValueError(f"unknown format '{name}' (one of {', '.join(format_names())})")


def _listing(specs: list[FormatSpec]) -> str:
    """'A, B or C' of the formats' inputs."""
    words = [s.input for s in specs]
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " or " + words[-1]


def titles(pixels: tuple[str, ...] | None = None) -> str:
    """'A, B and C': the titles of the formats (with one of the pixel policies `pixels`),
    for the help texts."""
    words = [s.title for s in REGISTRY if pixels is None or s.pixels in pixels]
    words = [w for w in words if w != "a native project"] if pixels is None else words
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]


def _missing(p: Path) -> str:
    """Why a path that does not exist as far as Path.exists sees: not found, a symbolic
    link loop, a name too long, a folder that cannot be searched."""
    from baarda.io.text_files import not_a_file

    return not_a_file(p, "not found") or "not found"


def detect(path: str | Path) -> str:
    """The format of `path` (one of format_names()); ProjectError if none fits."""
    p = Path(path)
    if not p.exists():
        raise ProjectError(str(p), _missing(p))
    for s in REGISTRY:
        if s.detects(p):
            return s.name
    if p.is_dir():
        from baarda.io.project import FILES

        has = [f for f in FILES[1:] if (p / f).is_file()]
        if has:
            raise ProjectError(str(p / "project.toml"), "not found: the folder has "
                               f"{', '.join(has)} but a native project needs project.toml "
                               "beside them (docs/format.md)")
        others = [s for s in REGISTRY if s.path != "file" and s.name != "project"]
        raise ProjectError(str(p), "format not recognised: no project.toml (a native project "
                           f"folder), and not {_listing(others)}")
    raise ProjectError(str(p), f"format not recognised: not {_listing(REGISTRY)}")


def _check_kind(p: Path, s: FormatSpec) -> None:
    """ProjectError when --format names a format whose input is a file and the path is a
    folder, or the other way round (the reader would say 'file not found')."""
    if not p.exists():
        raise ProjectError(str(p), _missing(p))
    wrong = (s.path == "file" and p.is_dir()) or (s.path == "folder" and p.is_file())
    if not wrong:
        return
    try:
        found = f"; it looks like {detect(p)} input (leave out --format)"
    except ProjectError:
        found = ""
    kind = "a folder" if p.is_dir() else "a file"
    raise ProjectError(str(p), f"--format {s.name} reads {s.input}, but this is {kind}{found}")


def read_any(path: str | Path, fmt: str | None = None, *, pixel_mm: float | None = None,
             sigma_px: float | None = None, sigma_image_um: float | None = None,
             encoding: str = ENCODING, camera: str | Path | None = None,
             crs: str | None = None, model: int | None = None,
             tie_points: str | Path | None = None) -> Block:
    """Read any registered input into a Block.

    pixel_mm, sigma_px, sigma_image_um: pixel size [mm] and image sigma [px] or [µm],
    resolved for the format by io/image_sigma.py (an option that does not apply to it is
    an error; None: the format's own); encoding: of the text files of a project, AICON or
    PhotoModeler input (COLMAP and BAL are UTF-8 / ASCII by definition, DBAT's XML names
    its own); camera: a DBAT camera file (a calibration result) replacing a DBAT script's
    camera; crs: the project CRS of an OpenSfM dataset (its topocentric frame is placed in
    it; other formats take the CRS in pipeline.read); model: of a file with several (NVM,
    0-based; None: the first); tie_points: a Bundler file of the chunk of a Metashape
    cameras XML (default: a bundle.out beside it, if any).  The cameras are as the files give
    them: pipeline.read applies the calibration group (settings.calibration_group).
    """
    from baarda.io.image_sigma import check_image_sigmas, resolve_image_options, with_image_sigma

    p = Path(path)
    if fmt is not None:
        try:
            s = spec(fmt)
        except ValueError as e:
            raise ProjectError(str(p), str(e)) from None
        _check_kind(p, s)
    else:
        s = spec(detect(p))
    if camera is not None and not s.camera_file:
        takes = " or ".join(r.title for r in REGISTRY if r.camera_file)
        raise ProjectError(str(camera), f"a camera file replaces the camera of a {takes}; "
                           f"{p.name} is {s.name} input (give its cameras in its own files)")
    if model is not None and not s.models:
        takes = " or ".join(r.title for r in REGISTRY if r.models)
        raise ProjectError(str(p), f"--model picks a model of a {takes} file; this is "
                           f"{s.name} input (one model)")
    if tie_points is not None and not s.tie_points:
        raise ProjectError(str(tie_points), "--tie-points joins the tie points of a Bundler "
                           f"file to a Metashape cameras XML; {p.name} is {s.name} input")
    opts = resolve_image_options(s.name, pixel_mm, sigma_px, sigma_image_um)
    block = s.reads(p, ReadRequest(opts.pixel_mm, opts.sigma_px, encoding,
                                   None if camera is None else Path(camera), crs, model,
                                   None if tie_points is None else Path(tie_points)))
    check_image_sigmas(block)
    return block if opts.sigma_um is None else with_image_sigma(block, opts.sigma_um)
