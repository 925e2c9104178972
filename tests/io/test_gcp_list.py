"""--gcp-list: OpenDroneMap's gcp_list.txt added to a COLMAP block (io/gcp_list.py,
block/gcp.py, block/pixels.py, gcp_placement.with_gcp_list): the reader, the pixel convention
against an independent projection (tests/gcp_blocks.py), bad input, the Monte Carlo
acceptance (issue 38) and the shared Maupertuis model."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from dense import dense_system
from docs_text import doc_says
from gcp_blocks import gcp_block, gcp_lines, write_colmap_text

from baarda.block.photo_block import Cameras
from baarda.block.pixels import mm_to_pixels, pixels_to_mm
from baarda.bundle.bundle_model import BundleModel
from baarda.errors import ProjectError
from baarda.io.gcp_list import read_gcp_list
from baarda.pipeline import adjust, assess, read, snoop
from baarda.quality.statistics import analyse

MAUPERTUIS = Path(__file__).resolve().parents[1] / "data" / "colmap_maupertuis" / "sparse"


def _files(tmp_path: Path, seed: int = 1, **kw) -> tuple[Path, Path, list]:
    b = gcp_block(0)
    rng = np.random.default_rng(seed)
    sigma_px = kw.pop("sigma_px", 1.0)
    write_colmap_text(b, tmp_path / "model", rng, sigma_px=sigma_px)
    lines, which = gcp_lines(b, rng, sigma_px=sigma_px, **kw)
    (tmp_path / "gcp_list.txt").write_text("\n".join(lines) + "\n")
    return tmp_path / "model", tmp_path / "gcp_list.txt", which


# ------------------------------------------------------------------ the reader
def test_reader_takes_odm_lines(tmp_path):
    p = tmp_path / "gcp_list.txt"
    p.write_text("# written by hand\nWGS84 UTM 32N\n"
                 "500010.5\t5400020.25\t301.5\t100\t200.5\tIMG_0001.JPG\tA extra words\n"
                 "# a comment\n\n"
                 "500010.5 5400020.25 301.5 1200 2200 IMG_0002.JPG A\n"
                 "500030 5400040 NaN 10 20 IMG_0001.JPG\n")
    g = read_gcp_list(p)
    assert g.crs == "EPSG:32632" and g.crs_line == 2
    assert g.ids == ["A", "500030_5400040_NaN"]  # unnamed: by its coordinates (as ODM)
    np.testing.assert_array_equal(g.xyz[0], [500010.5, 5400020.25, 301.5])
    assert np.isnan(g.xyz[1, 2]) and np.isfinite(g.xyz[1, :2]).all()
    assert g.gcp.tolist() == [0, 0, 1] and g.image == ["IMG_0001.JPG", "IMG_0002.JPG",
                                                       "IMG_0001.JPG"]
    np.testing.assert_array_equal(g.uv_px, [[100, 200.5], [1200, 2200], [10, 20]])
    assert g.line.tolist() == [3, 6, 7]


@pytest.mark.parametrize("text, line, field, words", [
    ("EPSG:32632\n1 2 3 4 5\n", 2, "image_name", "found 5 field(s)"),
    ("EPSG:32632\n1 2 3 4 x IMG A\n", 2, "im_y", "'x' is not a number"),
    ("EPSG:32632\n1 2 3 4 5 IMG A\n1 2 4 4 5 IMG2 A\n", 3, "geo_x", "other coordinates"),
    ("EPSG:32632\n", 2, None, "no GCP measurements"),
    ("# only a comment\n", None, None, "empty"),
])
def test_reader_refuses_bad_lines(tmp_path, text, line, field, words):
    p = tmp_path / "gcp_list.txt"
    p.write_text(text)
    with pytest.raises(ProjectError) as e:
        read_gcp_list(p)
    assert e.value.line == line and e.value.column == field and words in str(e.value)
    assert str(p) in str(e.value)


# ------------------------------------------------------------------ pixels
def test_pixel_convention_by_hand():
    """The first pixel's centre (0, 0) lies half a pixel inside the corner; the image centre
    is (W/2 - 0.5, H/2 - 0.5); y up; COLMAP's 0.5 convention shifts by half a pixel."""
    cams = Cameras(["1"], np.array([2.4]), np.zeros((1, 2)),
                   pixel_frame=np.array([[np.nan, np.nan, 0.001, 0.002]]),
                   image_size_px=np.array([[4000.0, 3000.0]]))
    uv = np.array([[0.0, 0.0], [1999.5, 1499.5], [3999.0, 2999.0]])
    xy = pixels_to_mm(cams, np.zeros(3, np.int64), uv)
    np.testing.assert_allclose(xy, [[-1.9995, 2.999], [0, 0], [1.9995, -2.999]], atol=1e-12)
    np.testing.assert_allclose(mm_to_pixels(cams, np.zeros(3, np.int64), xy), uv, atol=1e-9)
    colmap = pixels_to_mm(cams, np.zeros(1, np.int64), uv[:1] + 0.5, first_centre=0.5)
    np.testing.assert_allclose(colmap, xy[:1], atol=1e-12)


def test_noise_free_gcps_fit_the_independent_projection(tmp_path):
    """Without noise every GCP measurement, converted from ODM's pixels, fits the
    adjusted block to 1e-4 px (half a pixel off, or y the wrong way, would show as 0.5 px
    and more), and the block lands on the GCPs' UTM coordinates."""
    model, gcps, which = _files(tmp_path, sigma_px=0.0, sigma_m=0.0, xyz_noise=False)
    block = read(model, gcp_list=gcps)
    assert block.settings.crs == "EPSG:32632" and block.settings.datum == "control"
    assert (block.points.role == "control").sum() == 8
    res = adjust(block)
    t = assess(res).table()
    g = t[t["point"].astype(str).str.startswith("GCP") & (t["kind"] == "image")]
    assert len(g) == 2 * len(which)
    assert np.abs(g["residual"].to_numpy(float)).max() < 1e-4  # µm = px here
    assert np.abs(t["residual"].to_numpy(float)).max() < 1e-4
    # the pixels were placed with the camera's fx/fy scaling of y (0.995 mm per px)
    assert block.cameras.pixel_frame[0, 3] == pytest.approx(0.001 * 2400 / 2412)


def test_gcp_pixels_land_where_colmap_puts_the_same_ray(tmp_path):
    """Each GCP measurement's image coordinates equal the independent COLMAP projection of
    the GCP (u, v with the first pixel's centre at 0.5) in COLMAP's reading (x = (u - W/2)
    p, y = (H/2 - v) p fx/fy, io/colmap.py) to 1e-9 mm: ODM's pixel is that ray's u - 0.5.
    (A uniform half-pixel slip would not show in the adjustment above: the GCPs alone carry
    the datum, and the block turns with them.)"""
    from gcp_blocks import CX, CY, FX, FY, H, W

    model, gcps, which = _files(tmp_path, sigma_px=0.0, sigma_m=0.0, xyz_noise=False)
    block = read(model, gcp_list=gcps)
    b = gcp_block(0)
    uv, _ = b.project(b.gcps)
    im, pts = block.image, block.points
    for gcp, image in which:
        k = int(gcp[3:]) - 1
        i = int(image[4:8])
        row = np.flatnonzero((im.point == block.point_index[gcp])
                             & (im.photo == block.photo_index[image[:-4]]))
        assert len(row) == 1 and pts.role[im.point[row[0]]] == "control"
        u, v = uv[i, k]
        expected = [(u - W / 2) * 0.001, (H / 2 - v) * 0.001 * FX / FY]
        np.testing.assert_allclose(im.xy_mm[row[0]], expected, rtol=0, atol=1e-9)
    assert abs(CX - W / 2) > 1 and abs(CY - H / 2) > 1  # a principal point off the centre


# ------------------------------------------------------------------ bad input
def _replace_line(path: Path, k: int, f) -> None:
    lines = path.read_text().splitlines()
    lines[k] = f(lines[k])
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("change, line, field, words", [
    (lambda s: s.replace("IMG_", "NOPE_"), 2, "image_name", "is not a photo of"),
    (lambda s: " ".join(s.split()[:3] + ["5000"] + s.split()[4:]), 2, "im_x",
     "lies outside image"),
    (None, 3, "image_name", "measured twice on image"),
])
def test_block_refuses_bad_measurements(tmp_path, change, line, field, words):
    model, gcps, _ = _files(tmp_path)
    if change is None:  # the first measurement once more
        lines = gcps.read_text().splitlines()
        gcps.write_text("\n".join(lines[:2] + [lines[1]] + lines[2:]) + "\n")
    else:
        _replace_line(gcps, 1, change)
    with pytest.raises(ProjectError) as e:
        read(model, gcp_list=gcps)
    assert e.value.line == line and e.value.column == field and words in str(e.value)
    assert str(gcps) in str(e.value)


def test_gcps_drop_the_notes_on_the_input_control(tmp_path):
    """The GCPs replace the input's control as --control does (block/control.py): a
    reader's note about that control (INPUT_CONTROL) goes with it."""
    from dataclasses import replace

    from baarda.block.control import INPUT_CONTROL
    from baarda.block.gcp import add_gcps

    model, gcps, _ = _files(tmp_path)
    block = read(model)
    said = INPUT_CONTROL + "the coordinates the input lists"
    block = replace(block, notes=[*block.notes, said])
    notes = add_gcps(block, read_gcp_list(gcps)).notes
    assert said not in notes
    assert any(n.startswith("GCPs from ") for n in notes)


def test_crs_line_and_crs_option(tmp_path):
    model, gcps, _ = _files(tmp_path)
    _replace_line(gcps, 0, lambda s: "not a crs")
    with pytest.raises(ProjectError) as e:
        read(model, gcp_list=gcps)
    assert e.value.line == 1 and e.value.column == "crs"
    _replace_line(gcps, 0, lambda s: "EPSG:32632")
    with pytest.raises(ProjectError, match="--crs EPSG:25832 is not the CRS of the GCPs"):
        read(model, gcp_list=gcps, crs="EPSG:25832")
    assert read(model, gcp_list=gcps, crs="EPSG:32632").settings.crs == "EPSG:32632"


def test_control_and_gcp_list_together_are_refused(tmp_path):
    model, gcps, _ = _files(tmp_path)
    with pytest.raises(ProjectError, match="--control and --gcp-list both replace"):
        read(model, gcp_list=gcps, control=gcps)


def test_too_few_gcps_to_place_the_block(tmp_path):
    model, gcps, which = _files(tmp_path)
    lines = gcps.read_text().splitlines()
    keep = [lines[0]] + [s for s in lines[1:] if s.split()[6] in ("GCP1", "GCP2")]
    gcps.write_text("\n".join(keep) + "\n")
    with pytest.raises(ProjectError, match="2 GCP.s. with X, Y, Z measured on two or more"):
        read(model, gcp_list=gcps)


def test_a_gcp_without_height(tmp_path):
    """geo_z NaN (ODM: no value): a planimetric control point, its height approximated by
    intersection, only X and Y observed; measured on one image only it cannot be placed:
    exit 2 at its line, field geo_z."""
    model, gcps, _ = _files(tmp_path)
    lines = gcps.read_text().splitlines()
    nan = [lines[0]] + [" ".join(f[:2] + ["NaN"] + f[3:]) if f[6] == "GCP8" else s
                        for s, f in ((s, s.split()) for s in lines[1:])]
    gcps.write_text("\n".join(nan) + "\n")
    block = read(model, gcp_list=gcps)
    j = block.point_index["GCP8"]
    assert block.points.role[j] == "control" and np.isnan(block.points.sigma[j, 2])
    assert np.isfinite(block.points.xyz[j]).all()
    assert block.points.controlled[j].tolist() == [True, True, False]
    t = assess(adjust(block)).table()
    assert sorted(t.loc[(t["kind"] == "control") & (t["point"].astype(str) == "GCP8"),
                        "component"]) == ["X", "Y"]
    one = [s for s in nan if s.split()[-1] != "GCP8" or s == nan[0]]
    one += [next(s for s in nan[1:] if s.split()[-1] == "GCP8")]
    gcps.write_text("\n".join(one) + "\n")
    with pytest.raises(ProjectError) as e:
        read(model, gcp_list=gcps)
    assert (e.value.line, e.value.column) == (len(one), "geo_z")
    assert "GCP8 has no height and is measured on one image" in str(e.value)


def test_cli_exit_2_names_file_line_field(tmp_path):
    import subprocess
    import sys

    model, gcps, _ = _files(tmp_path)
    _replace_line(gcps, 3, lambda s: s.replace("IMG_", "NOPE_"))
    r = subprocess.run([sys.executable, "-m", "baarda", "adjust", str(model), "--gcp-list",
                        str(gcps), "-o", str(tmp_path / "out")], capture_output=True,
                       text=True)
    assert r.returncode == 2, r.stderr
    assert str(gcps) in r.stderr and "line 4" in r.stderr and "image_name" in r.stderr
    assert "Traceback" not in r.stderr


def test_cli_missing_or_fifo_gcp_list(tmp_path, capsys):
    import os

    from baarda.cli import main

    model, _, _ = _files(tmp_path)
    missing = tmp_path / "nope.txt"
    assert main(["adjust", str(model), "--gcp-list", str(missing), "-o",
                 str(tmp_path / "o")]) == 2
    assert f"{missing}: GCP list not found" in capsys.readouterr().err
    fifo = tmp_path / "fifo.txt"
    os.mkfifo(fifo)
    assert main(["adjust", str(model), "--gcp-list", str(fifo), "-o",
                 str(tmp_path / "o")]) == 2
    assert f"{fifo}: is a FIFO (named pipe), not a regular file" in capsys.readouterr().err


# ------------------------------------------------------------------ the GCP that is wrong
def _first_rejection(qc) -> tuple[str, str, str]:
    """(photo, point, component) of data snooping's first rejection."""
    step = next(s for s in qc.run.log if s.action == "reject")
    m = qc.model
    row = step.rows[0]
    return str(m.frame[row]), str(m.point[row]), str(m.component[row])


def test_snooping_names_the_gcp_marked_15_px_off(tmp_path):
    """One run through the files: GCP3 marked 15 px off on IMG_0004 is the first rejection
    of data snooping, named by its GCP and image; --check-gcp makes GCP8 a check point."""
    model, gcps, _ = _files(tmp_path, error=("GCP3", "IMG_0004.JPG", 15.0, 0.0))
    block = read(model, gcp_list=gcps, check_gcp="GCP8")
    assert block.points.role[block.point_index["GCP8"]] == "check"
    assert _first_rejection(snoop(block)) == ("IMG_0004", "GCP3", "x")


def test_the_command_names_the_wrong_gcp(tmp_path, capsys):
    """baarda adjust --gcp-list --snoop: the snooping log and the quality check name GCP3
    on IMG_0004, and the result folder holds it as a rejected image observation."""
    import pandas as pd

    from baarda.cli import main

    model, gcps, _ = _files(tmp_path, error=("GCP3", "IMG_0004.JPG", 15.0, 0.0))
    out = tmp_path / "out"
    main(["adjust", str(model), "--gcp-list", str(gcps), "--snoop", "-o", str(out)])
    text = " ".join(capsys.readouterr().out.split())
    assert "1 reject image photo IMG_0004 point GCP3 x w = " in text  # the first step
    assert "Suspicious GCPs: 1 image measurement(s) of GCPs rejected" in text
    assert "GCP3 on photo IMG_0004 (x)" in text
    obs = pd.read_csv(out / "observations.csv")
    bad = obs[(obs["point"].astype(str) == "GCP3") & (obs["photo"] == "IMG_0004")
              & (obs["component"] == "x")]
    assert bad["rejected"].tolist() == [True]


def test_convert_keeps_the_gcps(tmp_path, capsys):
    """baarda convert --gcp-list writes a native project in the GCPs' CRS that adjusts to
    the same sigma0 (1e-6, as written to the project's files) as the COLMAP model
    with the list."""
    from baarda.cli import main

    model, gcps, _ = _files(tmp_path)
    assert main(["convert", str(model), "--gcp-list", str(gcps), "-o",
                 str(tmp_path / "proj")]) == 0
    capsys.readouterr()
    back = read(tmp_path / "proj")
    assert back.settings.crs == "EPSG:32632" and (back.points.role == "control").sum() == 8
    assert adjust(back).sigma0 == pytest.approx(adjust(read(model, gcp_list=gcps)).sigma0,
                                                rel=1e-6)


def test_monte_carlo_the_wrong_gcp_is_named(tmp_path):
    """Issue 38's acceptance on the block's linearised model (the dense system of the
    adjusted block read from the files; w = (I - H)(e + b u_j) / sigma_v, 200 runs):

    * a 15 px marking error (x) of GCP3 on IMG_0004, 3.1 times its MDB (4.8 px), is the
      largest significant |w| (rejected and named first) in at least 80 % of the runs;
    * at exactly its MDB, its w-test rejects it in beta0 = 80 % of the runs (the MDB's
      definition; within 3 binomial standard deviations): being the largest |w| as well
      happens less often at that size (about 68 %), which is why the named size is larger;
    * without an error, the number of w-tests rejected per run averages alpha0 x n (within
      3 standard errors of the 200-run mean)."""
    model, gcps, _ = _files(tmp_path)
    res = adjust(read(model, gcp_list=gcps))
    bm = BundleModel(res)
    q = analyse(bm)
    t = assess(res).table()
    row = int(np.flatnonzero((t["point"].astype(str) == "GCP3") & (t["photo"] == "IMG_0004")
                             & (t["component"] == "x"))[0])
    a, p = dense_system(bm)
    m = np.eye(bm.n) - a @ np.linalg.solve(a.T @ (p[:, None] * a), a.T * p[None, :])
    tested = q.controlled & bm.active
    sd = np.sqrt(np.where(tested, q.qvv, 1.0))
    np.testing.assert_allclose(sd[tested] ** 2, (m * bm.sigma[None, :] ** 2)
                               .diagonal()[tested], rtol=1e-6)  # q_vv of the dense model
    runs = 200
    rng = np.random.default_rng(38)
    w0 = (m @ (rng.standard_normal((bm.n, runs)) * bm.sigma[:, None])) / sd[:, None]
    w0[~tested] = 0.0
    px = 0.001  # mm per pixel in x (COLMAP's nominal pixel)
    assert q.mdb[row] < 15 * px / 3

    def rates(bias: float) -> tuple[float, float]:
        w = np.abs(w0 + bias * (m[:, row] / sd * tested)[:, None])
        named = (np.argmax(w, axis=0) == row) & (w[row] > q.k_w)
        return float(named.mean()), float((w[row] > q.k_w).mean())

    named, _ = rates(15 * px)
    assert named >= 0.80
    named_at_mdb, power = rates(q.mdb[row])
    se = np.sqrt(q.beta0 * (1 - q.beta0) / runs)
    assert abs(power - q.beta0) < 3 * se, power
    false = (np.abs(w0) > q.k_w).sum(axis=0)
    expected = q.alpha0 * tested.sum()
    assert false.mean() <= expected + 3 * np.sqrt(expected / runs), (false.mean(), expected)
    assert doc_says("docs/formats.md", f"of {q.mdb[row] / px:.1f} px; marked 15 px off it is "
                    f"rejected and named first by data snooping in {100 * named:.0f} % of the "
                    f"runs (at least 80 % required); at exactly its MDB its w-test rejects it "
                    f"in {100 * power:.1f} % of the runs (beta0 80 %, within the binomial "
                    f"spread) and names it first in {100 * named_at_mdb:.1f} %; without an "
                    f"error, {false.mean():.2f} w-tests are rejected per run against alpha0 x "
                    f"n = {expected:.2f}")


@pytest.mark.slow
def test_monte_carlo_through_the_files(tmp_path):
    """The same acceptance without linearising: 20 runs, each with its own noise written
    to a COLMAP model and a gcp_list.txt, read and snooped by the pipeline; GCP3 marked
    15 px off on IMG_0004 is the first rejection in every run (at least 80 % required)."""
    named = 0
    for seed in range(20):
        folder = tmp_path / str(seed)
        model, gcps, _ = _files(folder, seed=100 + seed,
                                error=("GCP3", "IMG_0004.JPG", 15.0, 0.0))
        named += _first_rejection(snoop(read(model, gcp_list=gcps))) == \
            ("IMG_0004", "GCP3", "x")
    assert named == 20


# ------------------------------------------------------------------ a real model
def _maupertuis_gcps(folder: Path,
                     error_px: float = 0.0) -> tuple[Path, list[str], list[str]]:
    """A gcp_list.txt for the Maupertuis model from its own points: the points with
    the longest tracks spread over the scene (one per octant of the model around its
    median), their model coordinates carried into UTM 32N by a similarity (scale 2, a turn
    about the vertical, a UTM offset) as a surveyor would give them, measured where COLMAP
    measured them (ODM's pixels: COLMAP's x - 0.5, y - 0.5) on every image that sees them."""
    from baarda.io.colmap import read_colmap

    m = read_colmap(MAUPERTUIS)
    pt, im = m.points, m.images
    length = np.diff(pt.offsets)
    rel = pt.xyz - np.median(pt.xyz, axis=0)
    octant = (rel > 0) @ np.array([1, 2, 4])
    chosen = []
    for o in range(8):
        cand = np.flatnonzero(octant == o)
        if len(cand):
            far = np.linalg.norm(rel[cand], axis=1)
            chosen.append(int(cand[np.lexsort((-far, -length[cand]))[0]]))
    c, s = np.cos(0.4), np.sin(0.4)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    utm = 2.0 * pt.xyz @ rot.T + np.array([500_000.0, 5_400_000.0, 200.0])
    lines = ["WGS84 UTM 32N"]
    photo_of = im.image_of_keypoint()
    names = []
    for n, j in enumerate(chosen):
        name = f"M{n + 1}"
        names.append(name)
        on = set()
        for k in np.flatnonzero(im.point3D_ids == pt.ids[j]):
            if photo_of[k] in on:  # a second keypoint of the point in one image
                continue
            u, v = im.xys[k] - 0.5
            if n == 0 and not on:
                u += error_px
            on.add(photo_of[k])
            lines.append(" ".join(repr(float(x)) for x in (*utm[j], u, v))
                         + f" {im.names[photo_of[k]]} {name}")
    p = folder / "gcp_list.txt"
    p.write_text("\n".join(lines) + "\n")
    return p, names, [str(pt.ids[j]) for j in chosen]


def test_maupertuis_with_gcps_from_its_own_points(tmp_path):
    """The shared COLMAP model with seven of its own points as GCPs (_maupertuis_gcps):
    the block is placed in UTM at the similarity's scale 2; with --sigma-px 1 the GCPs'
    rays repeat tie points' rays, so sigma0 stays that of the model alone within 2 %; a
    15 px marking error on M1 is the first rejection of data snooping."""
    model = tmp_path / "sparse"
    shutil.copytree(MAUPERTUIS, model)
    gcps, names, tie_ids = _maupertuis_gcps(tmp_path)
    block = read(model, gcp_list=gcps, sigma_px=1.0)
    assert (block.points.role == "control").sum() == len(names) == 7  # an octant is empty
    import re

    scale = [float(m.group(1)) for n in block.notes for m in [re.search(r"scale ([0-9.]+)", n)]
             if m and "placed" in n]
    assert scale == [pytest.approx(2.0, rel=1e-3)]
    # the GCP's measurement is the very keypoint of its tie point: both readings agree
    im, index = block.image, block.point_index
    for name, tie in zip(names, tie_ids, strict=True):
        for photo in np.unique(im.photo[im.point == index[name]]):
            a = im.xy_mm[(im.point == index[name]) & (im.photo == photo)]
            b = im.xy_mm[(im.point == index[tie]) & (im.photo == photo)]
            np.testing.assert_allclose(a, b[:1], rtol=0, atol=1e-12)
    plain = adjust(read(model, sigma_px=1.0))
    res = adjust(block)
    assert res.sigma0 == pytest.approx(plain.sigma0, rel=0.02)
    bad, _, _ = _maupertuis_gcps(tmp_path, error_px=15.0)
    photo, point, component = _first_rejection(snoop(read(model, gcp_list=bad,
                                                          sigma_px=1.0)))
    assert (point, component) == ("M1", "x")


@pytest.mark.parametrize("fmt", ["bundler", "nvm"])
def test_bundler_and_nvm_take_the_image_size_from_the_images(tmp_path, fmt):
    """Bundler and NVM state no image size: their GCP pixels are placed with the size of
    the image files beside the input (Pillow reads the header; blank 1919 x 1079 JPEGs
    stand in for Maupertuis' photos), and then land exactly on the measurements of the same
    keypoints that the files hold from the image centre (the Maupertuis export of
    tests/io/sfm_exports.py, a writer other than baarda's).  Without the images: exit 2
    naming the line and field."""
    import sys

    from PIL import Image

    sys.path.insert(0, str(Path(__file__).parent))
    from sfm_exports import export_bundler, export_nvm

    (tmp_path / "bundler").mkdir()
    path = (export_bundler(MAUPERTUIS, tmp_path / "bundler") if fmt == "bundler" else
            export_nvm(MAUPERTUIS, tmp_path / "bundler" / "model.nvm"))
    gcps, names, tie_ids = _maupertuis_gcps(tmp_path)
    with pytest.raises(ProjectError) as e:
        read(path, gcp_list=gcps)
    assert e.value.column == "im_x" and e.value.line == 2 and "image size" in str(e.value)
    (tmp_path / "bundler" / "images").mkdir()
    for k in range(4):
        Image.new("L", (1919, 1079)).save(tmp_path / "bundler" / "images" / f"{k:02d}.jpg")
    block = read(path, gcp_list=gcps)
    np.testing.assert_array_equal(block.cameras.image_size_px, [[1919, 1079]])
    assert any("image size from the image files" in n for n in block.notes)
    # each GCP measurement coincides with a measurement of its tie point on that photo
    im, index = block.image, block.point_index
    checked = 0
    for name in names:
        g = im.point == index[name]
        for photo in np.flatnonzero(np.bincount(im.photo[g], minlength=len(block.photos))):
            here = im.xy_mm[g & (im.photo == photo)][0]
            same = np.abs(im.xy_mm[(im.photo == photo) & ~g] - here).max(axis=1)
            assert same.min() < 1e-9
            checked += 1
    assert checked >= 2 * len(names)
