"""The format registry (io/formats.py): one FormatSpec per reader; detection, dispatch,
errors, `--format` choices and the help texts come from it.  A new reader is one module
and one registry line: shown with a toy format registered here."""

import importlib
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from baarda.cli import main
from baarda.errors import ProjectError
from baarda.io import formats
from baarda.io.formats import FormatSpec, ReadRequest, detect, read_any, register, unregister
from baarda.io.image_sigma import resolve_image_options
from baarda.pipeline import read

ROOT = Path(__file__).parents[2]
DEMO = ROOT / "examples" / "demo"


# ------------------------------------------------------------------ the toy reader module
# A toy format: a file `*.toy` holding the path of a native project (as a reader of another
# program's format would parse its own file); its pixels have a nominal size.
def is_toy(path: Path) -> bool:
    return path.suffix == ".toy"


def read_toy(path: Path, request: ReadRequest):
    from dataclasses import replace

    from baarda.io.project import read_project

    block = read_project(Path(path.read_text(encoding="utf-8").strip()), request.encoding)
    # the toy's image sigma: request.sigma_px of its nominal pixel request.pixel_mm
    sigma_mm = np.full(len(block.image), request.sigma_px * request.pixel_mm)
    return replace(block, image=replace(block.image, sigma_mm=sigma_mm, sigma_xy_mm=None),
                   source=str(path))


TOY = FormatSpec("toy", "Toy", "a toy file .toy", "file", "nominal", is_toy, read_toy)


@pytest.fixture
def toy(tmp_path):
    register(TOY)  # the one registry line
    f = tmp_path / "block.toy"
    f.write_text(str(DEMO), encoding="utf-8")
    yield f
    unregister("toy")


def test_a_registered_format_is_detected_read_and_offered(toy, tmp_path, capsys):
    assert detect(toy) == "toy"
    b = read(toy)  # the pixel policy "nominal": 1 px of 1 µm unless given
    assert np.allclose(b.image.sigma_mm, 0.001) and b.source == str(toy)
    assert np.allclose(read(toy, sigma_px=2, pixel_mm=0.004).image.sigma_mm, 0.008)
    assert np.allclose(read(toy, "toy", sigma_image_um=3).image.sigma_mm, 0.003)
    # the command line offers it and adjusts it like any input
    assert main(["adjust", str(toy), "--format", "toy", "-o", str(tmp_path / "o"), "-q",
                 "--sigma-image-um", "5"]) == 0
    ref = tmp_path / "ref"
    assert main(["adjust", str(DEMO), "-o", str(ref), "-q"]) == 0
    got, want = (json.loads((d / "summary.json").read_text()) for d in (tmp_path / "o", ref))
    assert got["sigma0"] == want["sigma0"] and got["n_unknowns"] == want["n_unknowns"]
    capsys.readouterr()
    with pytest.raises(SystemExit):
        main(["adjust", "--help"])
    assert "toy: a toy file .toy" in " ".join(capsys.readouterr().out.split())
    # its kind of path: a folder given as --format toy is named as such
    with pytest.raises(ProjectError, match="--format toy reads a toy file .toy, but this "
                       "is a folder; it looks like project input"):
        read_any(DEMO, "toy")
    # the errors list it
    with pytest.raises(ProjectError, match="a toy file .toy"):
        detect(tmp_path / "o" / "summary.json")
    with pytest.raises(ValueError, match="registered already"):
        register(TOY)


def test_unknown_format_and_wrong_kind_name_the_registry():
    with pytest.raises(ProjectError, match="unknown format 'nope' \\(one of project, colmap, "
                       "aicon, micmac, opensfm, dbat, photomodeler, bal, bundler, nvm, metashape, "
                       "metashape-xml, patb, bingo\\)"):
        read_any(DEMO, "nope")
    with pytest.raises(ValueError, match="path one of"):
        FormatSpec("x", "X", "an x", "disk", "mm", is_toy, read_toy)


def test_pixel_policy_comes_from_the_spec():
    """io/image_sigma.py asks the spec, not a list of names."""
    assert {s.name: s.pixels for s in formats.REGISTRY} == {
        "project": "mm", "colmap": "nominal", "aicon": "mm", "micmac": "camera",
        "opensfm": "nominal", "dbat": "camera", "photomodeler": "header", "bal": "nominal",
        "bundler": "nominal", "nvm": "nominal", "metashape": "header",
        "metashape-xml": "header", "patb": "mm", "bingo": "header"}
    assert resolve_image_options("bal").pixel_mm == 0.001
    with pytest.raises(ProjectError, match="--pixel-mm does not apply to MicMac input"):
        resolve_image_options("micmac", pixel_mm=0.01)
    assert resolve_image_options("photomodeler", pixel_mm=0.01).pixel_mm == 0.01
    # every spec's functions exist (imported here, on demand in a run)
    for s in formats.REGISTRY:
        for ref in (s.detect, s.read) + ((s.writer,) if s.writer else ()):
            module, name = ref.split(":")
            assert callable(getattr(importlib.import_module(module), name)), ref


def test_read_request_encoding_is_the_readers():
    from baarda.io.text_files import ENCODING

    assert ReadRequest().encoding == formats.ENCODING == ENCODING


def test_reading_stays_lazy():
    """`baarda --help` imports no reader; recognising a native project imports no other
    reader (docs/architecture.md, "What is imported when")."""
    code = ("import sys; from baarda.cli import main\n"
            "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
            "from baarda.io.formats import detect\n"
            "before = {m for m in sys.modules if m.startswith('baarda.io.')}\n"
            f"detect({str(DEMO)!r})\n"
            "after = {m for m in sys.modules if m.startswith('baarda.io.')}\n"
            "print(sorted(before)); print(sorted(after - before))\n"
            "print('numpy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout.splitlines()
    readers = ("colmap", "aicon", "micmac", "opensfm", "dbat", "photomodeler", "bal",
               "project")
    assert not [m for m in eval(out[-3]) if m.split(".")[-1] in readers], out[-3]
    assert not [m for m in eval(out[-2]) if m.split(".")[-1] in readers], out[-2]
    assert out[-1] == "False"  # the registry (help texts, detection) costs no numpy
