"""Hostile and broken files cost seconds and megabytes, never the machine (issue 19).

Each case is bounded inside the test: wall time, and the peak of Python's allocations
(tracemalloc, which NumPy and bz2 report to); the command-line cases in a child process by
its own maximum resident set size."""

import json
import shutil
import struct
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import pytest

from baarda.errors import ProjectError
from baarda.io.bal import read_bal
from baarda.io.colmap import read_colmap
from baarda.io.dbat import read_dbat
from baarda.io.project import read_project
from baarda.io.xmltree import MAX_DEPTH, parse_xml
from baarda.output.format_files import write_colmap

DATA = Path(__file__).resolve().parents[1] / "data"
BOMB = DATA / "hostile" / "bal-bomb-2gb.txt.bz2"
DEMO = Path(__file__).resolve().parents[2] / "examples" / "demo"
COLMAP = DATA / "colmap_maupertuis" / "sparse"


def bounded(func, seconds: float = 2.0, megabytes: float = 100.0):
    """Run func(); return its ProjectError, and check time and peak Python memory."""
    tracemalloc.start()
    t0 = time.perf_counter()
    try:
        with pytest.raises(ProjectError) as e:
            func()
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    assert time.perf_counter() - t0 < seconds
    assert peak < megabytes * 2**20, f"{peak / 2**20:.0f} MB"
    return e.value


def laughs(levels: int = 9) -> str:
    ents = ['<!ENTITY lol "lol">'] + [
        f'<!ENTITY lol{i} "{("&lol" + (str(i - 1) if i > 1 else "") + ";") * 10}">'
        for i in range(1, levels + 1)]
    return ('<?xml version="1.0"?>\n<!DOCTYPE lolz [\n' + "\n".join(ents) + "\n]>\n"
            f'<document dbat_script_version="1.0"><project><name>&lol{levels};</name>'
            "</project></document>\n")


def test_billion_laughs_is_refused(tmp_path):
    f = tmp_path / "bomb.xml"
    f.write_text(laughs())
    err = bounded(lambda: read_dbat(f))
    assert err.path == str(f) and err.line == 2 and "document type" in err.detail


def test_quadratic_blowup_and_external_entities_are_refused(tmp_path):
    big = "x" * 100_000
    f = tmp_path / "quad.xml"
    f.write_text(f'<?xml version="1.0"?>\n<!DOCTYPE d [<!ENTITY a "{big}">]>\n'
                 f'<document dbat_script_version="1.0">{"&a;" * 20_000}</document>\n')
    assert "document type" in bounded(lambda: parse_xml(f)).detail
    secret = tmp_path / "secret.txt"
    secret.write_text("secret")
    g = tmp_path / "ext.xml"
    g.write_text(f'<?xml version="1.0"?>\n<!DOCTYPE d [<!ENTITY e SYSTEM "{secret}">]>\n'
                 '<document dbat_script_version="1.0">&e;</document>\n')
    assert "document type" in bounded(lambda: parse_xml(g)).detail


def test_deeply_nested_xml(tmp_path):
    f = tmp_path / "deep.xml"
    f.write_text("<a>" * 100_000 + "</a>" * 100_000)
    err = bounded(lambda: parse_xml(f))
    assert f"deeper than {MAX_DEPTH}" in err.detail and err.line == 1
    ok = tmp_path / "ok.xml"
    ok.write_text("<a>" * (MAX_DEPTH - 1) + "</a>" * (MAX_DEPTH - 1))
    assert parse_xml(ok).tag == "a"


def test_bz2_bomb_stops_at_the_header_counts():
    err = bounded(lambda: read_bal(BOMB), seconds=2.0, megabytes=50.0)
    assert "more data than the header's counts" in err.detail and err.line == 2


@pytest.mark.parametrize("text, message, line", [
    ("2 2 1000000\n0 0 1 2\n0 1 3 4\n", "1000000 observation lines announced", 3),
    ("1 1 1\n0 0 1 2\n" + "1\n" * 12 + "7\n" * 10_000, "values after the last point", 15),
    ("1 1 1\n0 0 1 2\n" + "1 " * 10_000_000 + "\n", "more data than the header", 3),
])
def test_bal_header_counts_that_lie(tmp_path, text, message, line):
    f = tmp_path / "lie.txt"
    f.write_text(text)
    err = bounded(lambda: read_bal(f), megabytes=200.0)
    assert message in err.detail and err.line == line


def test_a_line_of_ten_million_fields(tmp_path):
    import shutil

    proj = tmp_path / "p"
    shutil.copytree(DEMO, proj)
    with open(proj / "image_points.csv", "a") as f:
        f.write("01001," + ",".join(["7"] * 10_000_000) + "\n")
    err = bounded(lambda: read_project(proj), seconds=5.0, megabytes=200.0)
    assert err.line == 278 and "expected" in err.detail


def _colmap_bin(tmp_path) -> Path:
    """The Maupertuis model as binary files (and the COLMAP kernels compiled or loaded)."""
    folder = tmp_path / "bin"
    write_colmap(read_colmap(COLMAP), folder, binary=True)
    read_colmap(folder)
    return folder


HUGE = 10**12


@pytest.mark.parametrize("case, message", [
    ("keypoints", "file ends inside keypoints of image 7 (byte 86)"),
    ("images", "file ends inside image 1 (byte 110)"),
    ("all_ones", "file ends inside image 0 (byte 8)"),
    ("track", "file ends inside track of point 9 (byte 59)"),
    ("points", "file ends inside point 1 (byte 59)"),
    ("unterminated", "unterminated name of image 7 (byte 72)"),
    ("count", "file ends inside keypoint count of image 7 (byte 78)"),
    ("after", "3 bytes after the last record"),
])
def test_colmap_binary_counts_that_lie(tmp_path, case, message):
    """A count field that claims 10**12 keypoints, track elements or records is an error
    before anything of that size is allocated; truncated records are named as before."""
    folder = _colmap_bin(tmp_path)
    head = struct.pack("<I7dI", 7, 1, 0, 0, 0, 0, 0, 0, 1) + b"a.jpg\0"
    if case == "keypoints":
        name, data = "images", struct.pack("<Q", 1) + head + struct.pack("<Q", HUGE) + bytes(99)
    elif case == "images":
        name, data = "images", struct.pack("<Q", HUGE) + head + struct.pack("<Q", 1) + bytes(
            24 + 10)
    elif case == "all_ones":
        name, data = "images", b"\xff" * 8 + bytes(50)
    elif case == "unterminated":
        name, data = "images", struct.pack("<Q", 1) + head[:64] + b"abc"
    elif case == "count":
        name, data = "images", struct.pack("<Q", 1) + head + b"\1\0"
    elif case == "after":
        name, data = "images", struct.pack("<Q", 1) + head + bytes(8) + b"xyz"
    elif case == "track":
        name, data = "points3D", struct.pack("<Q", 1) + struct.pack(
            "<Q3d3BdQ", 9, 0, 0, 0, 1, 2, 3, 0.5, HUGE) + bytes(99)
    else:
        name, data = "points3D", struct.pack("<Q", HUGE) + struct.pack(
            "<Q3d3BdQ", 9, 0, 0, 0, 1, 2, 3, 0.5, 0) + bytes(10)
    (folder / f"{name}.bin").write_bytes(data)
    err = bounded(lambda: read_colmap(folder), seconds=2.0, megabytes=20.0)
    assert Path(err.path).name == f"{name}.bin" and err.detail == message


def test_colmap_huge_binary_keypoint_count_in_a_real_file(tmp_path):
    """The last image of a real images.bin claims 10**12 keypoints."""
    folder = _colmap_bin(tmp_path)
    data = bytearray((folder / "images.bin").read_bytes())
    model = read_colmap(folder)
    last = model.images.keypoint_counts[-1]
    at = len(data) - 24 * int(last) - 8  # the count of the last image
    assert struct.unpack_from("<Q", data, at)[0] == last
    data[at:at + 8] = struct.pack("<Q", HUGE)
    (folder / "images.bin").write_bytes(bytes(data))
    err = bounded(lambda: read_colmap(folder), seconds=2.0, megabytes=20.0)
    assert err.detail == f"file ends inside keypoints of image {model.images.ids[-1]} " \
                         f"(byte {at + 8})"
    shutil.rmtree(folder)


def _run(args, seconds: float) -> tuple[int, str, float, float]:
    """(exit code, stderr, wall time in s, maximum resident set size in MB) of `python -m
    baarda ARGS`, started from a small interpreter: Linux carries a process's peak across
    fork and exec, so a child forked from pytest would report pytest's own size."""
    script = ("import json, resource, subprocess, sys, time\n"
              "t0 = time.perf_counter()\n"
              "p = subprocess.run(sys.argv[2:], capture_output=True, text=True,\n"
              "                   timeout=float(sys.argv[1]))\n"
              "wall = time.perf_counter() - t0\n"
              "rss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss\n"
              "print(json.dumps([p.returncode, p.stderr, wall, rss]))\n")
    out = subprocess.run([sys.executable, "-c", script, str(seconds), sys.executable, "-m",
                          "baarda", *args], capture_output=True, text=True,
                         timeout=seconds + 30, check=True).stdout
    code, err, wall, kb = json.loads(out)
    return code, err, wall, kb / 1024


def test_command_line_ends_hostile_files_quickly(tmp_path):
    """The issue's acceptance: exit 2 and a clear message in < 2 s and < 300 MB, the whole
    process included (the command reads its input before it imports the computation:
    about 45 MB and 0.2 s here, where the imports of `baarda adjust` on a good file take
    over 300 MB)."""
    bomb = tmp_path / "bomb.xml"
    bomb.write_text(laughs())
    for f in (bomb, BOMB):
        code, err, wall, rss = _run(["adjust", str(f), "-o", str(tmp_path / "out")], 30)
        assert code == 2 and str(f) in err and "Traceback" not in err
        assert wall < 2.0
        assert rss < 300
        assert not (tmp_path / "out").exists()
