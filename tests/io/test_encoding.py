"""Text encodings: UTF-8 with or without a byte-order mark; any other named with
--encoding; undecodable bytes name the file and the line (issue 15)."""

import shutil
from pathlib import Path

import numpy as np
import pytest

from baarda.cli import main
from baarda.errors import ProjectError
from baarda.io.project import read_project
from baarda.pipeline import read

DEMO = Path(__file__).parents[2] / "examples" / "demo"


@pytest.fixture
def latin1(tmp_path):
    """The demo with a control point named 'Pünkt3' written in latin-1 (line 4)."""
    dst = tmp_path / "demo"
    shutil.copytree(DEMO, dst)
    old = (dst / "ground_points.csv").read_text().splitlines()[3].split(",")[0]
    for name in ("ground_points.csv", "image_points.csv"):
        p = dst / name
        p.write_bytes(p.read_text(encoding="utf-8").replace(old, "Pünkt3").encode("latin-1"))
    return dst


def test_undecodable_bytes_name_file_and_line(latin1, capsys):
    with pytest.raises(ProjectError) as e:
        read_project(latin1)
    assert e.value.path.endswith("ground_points.csv") and e.value.line == 4
    assert "not utf-8 text: byte 0xfc" in e.value.detail and "--encoding" in e.value.detail
    assert main(["adjust", str(latin1), "-o", str(latin1.parent / "out"), "-q"]) == 2
    assert "ground_points.csv, line 4: not utf-8 text: byte 0xfc" in capsys.readouterr().err


def test_the_named_encoding_reads_it(latin1, tmp_path, capsys):
    block = read(latin1, encoding="latin-1")
    assert "Pünkt3" in block.points.ids
    ref = read(DEMO)
    assert np.array_equal(block.image.xy_mm, ref.image.xy_mm)
    out = tmp_path / "out"
    assert main(["adjust", str(latin1), "-o", str(out), "-q", "--encoding", "latin-1"]) == 0
    assert "Pünkt3" in (out / "points.csv").read_text(encoding="utf-8")  # written as UTF-8


def test_byte_order_mark_and_unknown_encoding(tmp_path):
    dst = tmp_path / "demo"
    shutil.copytree(DEMO, dst)
    for name in ("photos.csv", "project.toml"):
        p = dst / name
        p.write_bytes(b"\xef\xbb\xbf" + p.read_bytes())
    block = read_project(dst)
    assert block.photos.ids == read_project(DEMO).photos.ids
    with pytest.raises(ProjectError, match="unknown text encoding 'klingon'"):
        read_project(dst, encoding="klingon")
