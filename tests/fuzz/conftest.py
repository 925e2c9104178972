"""The valid inputs that the fuzz suite mutates (session fixtures, each read once here so
that the numba kernels are compiled before any example runs under a deadline)."""

import shutil
import struct
import tempfile
from pathlib import Path

import numpy as np
import pytest
from fuzz.fuzzing import Base, load_base

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data"
DEMO = ROOT / "examples" / "demo"
MAUPERTUIS = DATA / "colmap_maupertuis" / "sparse"
CAMCAL = DATA / "dbat_camcal_closerange" / "dbat_script"
SXB = DATA / "dbat_sxb_aerial" / "dbat_script"
PMEXPORT = DATA / "dbat_sxb_aerial" / "photomodeler_export" / "wsmart-no-orient-pmexport.txt"


def pytest_terminal_summary(terminalreporter):
    from fuzz.fuzzing import OUTCOMES

    for (what, outcome), n in sorted(OUTCOMES.items()):
        terminalreporter.write_line(f"{n:6d}  {what:20s} {outcome}")


@pytest.fixture(scope="session")
def work(tmp_path_factory):
    """A folder for the examples' temporary folders."""
    return tmp_path_factory.mktemp("fuzz")


def example_dir(work: Path) -> tempfile.TemporaryDirectory:
    return tempfile.TemporaryDirectory(dir=work)


def _checked(base: Base, work: Path, name: str, read) -> Base:
    """`base`, after reading it once unchanged (the unmutated base must be valid)."""
    root = work / f"base-{name}"
    from fuzz.fuzzing import write_files

    write_files(root, base.files)
    read(root)
    shutil.rmtree(root)
    return base


# ------------------------------------------------------------------ native projects
@pytest.fixture(scope="session")
def project_base(work):
    from baarda.pipeline import read

    kinds = {"project.toml": "toml", "cameras.csv": "csv", "photos.csv": "csv",
             "image_points.csv": "csv", "ground_points.csv": "csv"}
    return _checked(load_base(DEMO, kinds), work, "project", read)


@pytest.fixture(scope="session")
def model_base(work):
    from baarda.cli import main
    from baarda.pipeline import read_models

    folder = work / "simulated-models"
    assert main(["simulate-models", "-o", str(folder), "--strips", "2", "--models", "3",
                 "--seed", "5"]) == 0
    kinds = {"project.toml": "toml", "models.csv": "csv", "ground_points.csv": "csv"}
    return _checked(load_base(folder, kinds), work, "models", read_models)


# ------------------------------------------------------------------ COLMAP
def small_colmap(model, n_points: int):
    """The model with its first `n_points` points of three or more rays and only the
    keypoints of those points (keypoint indices of the tracks renumbered)."""
    from baarda.io.colmap_model import ColmapImages, ColmapModel, ColmapPoints

    im, pt = model.images, model.points
    keep_pt = np.flatnonzero(pt.track_lengths >= 3)[:n_points]
    kept = np.zeros(len(pt), bool)
    kept[keep_pt] = True
    keep_kp = np.isin(im.point3D_ids, pt.ids[kept])
    counts = np.bincount(im.image_of_keypoint()[keep_kp], minlength=len(im))
    offsets = np.zeros(len(im) + 1, np.int64)
    np.cumsum(counts, out=offsets[1:])
    rank = np.cumsum(keep_kp) - 1  # new global position of each kept keypoint
    images = ColmapImages(im.ids.copy(), im.qvec.copy(), im.tvec.copy(), im.camera_id.copy(),
                          list(im.names), offsets, im.xys[keep_kp].copy(),
                          im.point3D_ids[keep_kp].copy())
    el = np.repeat(kept, pt.track_lengths)
    row = im.rows(pt.image_ids[el])
    old = im.offsets[row] + pt.point2D_idxs[el]
    new_idx = rank[old] - offsets[row]
    toff = np.zeros(int(kept.sum()) + 1, np.int64)
    np.cumsum(pt.track_lengths[kept], out=toff[1:])
    points = ColmapPoints(pt.ids[kept].copy(), pt.xyz[kept].copy(), pt.rgb[kept].copy(),
                          pt.error[kept].copy(), toff, pt.image_ids[el].copy(), new_idx)
    return ColmapModel(dict(model.cameras), images, points)


def binary_fields(files: dict[str, bytes]) -> dict[str, list[tuple[int, str]]]:
    """The count, id and number fields of COLMAP binary files (offset, struct format):
    every header field, and the first three keypoints / track elements of each record."""
    from baarda.io.colmap_model import MODELS

    out = {}
    data = files["cameras.bin"]
    f = [(0, "<Q")]
    pos = 8
    for _ in range(struct.unpack_from("<Q", data)[0]):
        mid = struct.unpack_from("<i", data, pos + 4)[0]
        f += [(pos, "<i"), (pos + 4, "<i"), (pos + 8, "<Q"), (pos + 16, "<Q")]
        f += [(pos + 24 + 8 * k, "<d") for k in range(MODELS[mid][1])]
        pos += 24 + 8 * MODELS[mid][1]
    out["cameras.bin"] = f
    data = files["images.bin"]
    f = [(0, "<Q")] * 5
    pos = 8
    for _ in range(struct.unpack_from("<Q", data)[0]):
        f += [(pos, "<I")] + [(pos + 4 + 8 * k, "<d") for k in range(7)] + [(pos + 60, "<I")]
        end = data.index(b"\0", pos + 64)
        n = struct.unpack_from("<Q", data, end + 1)[0]
        f += [(end, "<B"), (end + 1, "<Q"), (end + 1, "<Q")]
        kp = end + 9
        for k in range(min(n, 3)):
            f += [(kp + 24 * k, "<d"), (kp + 24 * k + 8, "<d"), (kp + 24 * k + 16, "<Q")]
        pos = kp + 24 * n
    out["images.bin"] = f
    data = files["points3D.bin"]
    f = [(0, "<Q")] * 5
    pos = 8
    for _ in range(struct.unpack_from("<Q", data)[0]):
        n = struct.unpack_from("<Q", data, pos + 43)[0]
        f += [(pos, "<Q"), (pos + 8, "<d"), (pos + 16, "<d"), (pos + 24, "<d"),
              (pos + 32, "<B"), (pos + 35, "<d"), (pos + 43, "<Q")]
        for k in range(min(n, 3)):
            f += [(pos + 51 + 8 * k, "<I"), (pos + 55 + 8 * k, "<I")]
        pos += 51 + 8 * n
    out["points3D.bin"] = f
    return out


@pytest.fixture(scope="session")
def colmap_model():
    from baarda.io.colmap import read_colmap

    return read_colmap(MAUPERTUIS)


@pytest.fixture(scope="session")
def colmap_full_base(work):
    from baarda.pipeline import read

    kinds = {f"{n}.txt": "text" for n in ("cameras", "images", "points3D")}
    return _checked(load_base(MAUPERTUIS, kinds), work, "colmap-full", read)


def _colmap_base(work, model, binary: bool, name: str) -> Base:
    from baarda.output.format_files import write_colmap
    from baarda.pipeline import read

    folder = work / name
    write_colmap(model, folder, binary=binary)
    ext = ".bin" if binary else ".txt"
    kinds = {f"{n}{ext}": "bin" if binary else "text"
             for n in ("cameras", "images", "points3D")}
    base = load_base(folder, kinds)
    if binary:
        base.fields = binary_fields(base.files)
    return _checked(base, work, name, read)


@pytest.fixture(scope="session")
def colmap_text_base(work, colmap_model):
    return _colmap_base(work, small_colmap(colmap_model, 60), False, "colmap-text")


@pytest.fixture(scope="session")
def colmap_bin_base(work, colmap_model):
    return _colmap_base(work, small_colmap(colmap_model, 60), True, "colmap-bin")


# ------------------------------------------------------------------ BAL
def synthetic_bal(ncam: int = 5, npt: int = 24, seed: int = 3):
    """A BAL problem of cameras round a cloud of points, projected by BAL's model."""
    from baarda.io.bal import BalProblem, rodrigues, rotation_vector

    rng = np.random.default_rng(seed)
    pts = rng.uniform(-1, 1, (npt, 3)) * [2, 2, 0.5]
    cams = np.zeros((ncam, 9))
    for i in range(ncam):
        ang = 2 * np.pi * i / ncam
        centre = np.array([3 * np.cos(ang), 3 * np.sin(ang), 2.0])
        z = centre / np.linalg.norm(centre)
        x = np.cross([0, 0, 1.0], z)
        x /= np.linalg.norm(x)
        r = np.vstack([x, np.cross(z, x), z])
        cams[i, :3] = rotation_vector(r)
        cams[i, 3:6] = -r @ centre
        cams[i, 6:9] = [500 + 20 * i, -0.05, 0.01]
    cam, pt = np.repeat(np.arange(ncam), npt), np.tile(np.arange(npt), ncam)
    c = cams[cam]
    pc = np.einsum("mij,mj->mi", rodrigues(c[:, :3]), pts[pt]) + c[:, 3:6]
    q = -pc[:, :2] / pc[:, 2:3]
    n2 = np.sum(q**2, axis=1)
    xy = (c[:, 6] * (1 + c[:, 7] * n2 + c[:, 8] * n2**2))[:, None] * q
    return BalProblem(cams, pts, cam, pt, xy + rng.normal(0, 0.5, xy.shape))


@pytest.fixture(scope="session", params=["problem.txt", "problem.txt.bz2"])
def bal_base(work, request):
    from baarda.output.format_files import write_bal
    from baarda.pipeline import read

    name = request.param
    folder = work / f"bal-{name}"
    write_bal(synthetic_bal(), folder / name)
    base = load_base(folder, {name: "bz2" if name.endswith(".bz2") else "text"})
    return _checked(base, work, f"bal-{name}", lambda root: read(root / name))


# ------------------------------------------------------------------ DBAT
@pytest.fixture(scope="session")
def dbat_base(work):
    from baarda.pipeline import read

    kinds = {"camcaldemo.xml": "xml", "images/images.txt": "csv",
             "measurements/markpts.txt": "csv", "reference/camcal-fixed.txt": "csv"}
    return _checked(load_base(CAMCAL, kinds), work, "dbat",
                    lambda root: read(root / "camcaldemo.xml"))


@pytest.fixture(scope="session")
def dbat_sxb_base(work):
    from baarda.pipeline import read

    kinds = {"sxb.xml": "xml", "images/images.txt": "csv", "measurements/markpts.txt": "csv",
             "measurements/smartpts.txt": "csv", "reference/sxb-control.txt": "csv"}
    return _checked(load_base(SXB, kinds), work, "dbat-sxb", lambda root: read(root / "sxb.xml"))


# ------------------------------------------------------------------ AICON
def synthetic_aicon():
    """A small AICON project (2 strips x 4 photos of a simulated aerial block, mm)."""
    from baarda.io.aicon import AiconProject
    from baarda.simulate.aerial import FlightPlan, simulate_block

    block, truth = simulate_block(FlightPlan(strips=2, photos_per_strip=4, relief_m=30.0,
                                             seed=3))
    n, m, k = len(block.photos), len(block.points), len(block.image)
    one, zero = np.ones, np.zeros
    cameras = {"id": one(1), "internal": zero(1), "ck": -block.cameras.focal_mm[:1],
               "xh": zero(1), "yh": zero(1), "A1": zero(1), "A2": zero(1), "R0": zero(1),
               "A3": zero(1), "B1": zero(1), "B2": zero(1), "C1": zero(1), "C2": zero(1),
               "width_mm": np.full(1, 230.0), "height_mm": np.full(1, 230.0),
               "nx": np.full(1, 11500.0), "ny": np.full(1, 11500.0)}
    eo = block.photos.eo
    images = {"id": np.arange(1.0, n + 1), "camera": one(n), "X0": eo[:, 0] * 1e3,
              "Y0": eo[:, 1] * 1e3, "Z0": eo[:, 2] * 1e3, "omega": eo[:, 3], "phi": eo[:, 4],
              "kappa": eo[:, 5], "order": zero(n), "status": np.full(n, 307.0),
              "orient": np.full(n, 3.0)}
    xyz = np.array([truth["points"][p] for p in block.points.ids]) * 1e3
    ids = np.array([float(int(p)) for p in block.points.ids])
    points = {"id": ids, "X": xyz[:, 0], "Y": xyz[:, 1], "Z": xyz[:, 2],
              "sX": np.full(m, 0.01), "sY": np.full(m, 0.01), "sZ": np.full(m, 0.01),
              "rays": block.rays().astype(float), "status": one(m), "new": zero(m),
              "datum": zero(m)}
    im = block.image
    obs = {"image": im.photo + 1.0, "point": ids[im.point], "x": im.xy_mm[:, 0],
           "y": im.xy_mm[:, 1], "sx": np.full(k, 0.005), "sy": np.full(k, 0.005),
           "vx": zero(k), "vy": zero(k), "method": one(k), "status": one(k),
           "internal": one(k)}
    scale = {"id": np.array([1.0]), "name": np.array(["bar"]), "a": ids[:1], "b": ids[1:2],
             "length": np.array([1000.0]), "sigma": np.array([0.01]), "status": one(1)}
    return AiconProject("fuzz", Path("."), cameras, images, points, obs, scale)


@pytest.fixture(scope="session")
def aicon_base(work):
    from baarda.output.format_files import write_aicon
    from baarda.pipeline import read

    folder = work / "aicon"
    write_aicon(synthetic_aicon(), folder)
    kinds = {f"fuzz.{e}": "text" for e in ("ior", "eor", "obc", "phc", "scale")}
    return _checked(load_base(folder, kinds), work, "aicon",
                    lambda root: read(root / "fuzz.phc"))


# ------------------------------------------------------------------ PhotoModeler
@pytest.fixture(scope="session")
def photomodeler_base(work):
    from baarda.pipeline import read

    base = load_base(PMEXPORT.parent, {PMEXPORT.name: "text"})
    return _checked(base, work, "photomodeler", lambda root: read(root / PMEXPORT.name))


# ------------------------------------------------------------------ OpenSfM
@pytest.fixture(scope="session")
def opensfm_base(work):
    """OpenSfM's berlin example cut to its first 40 points with their tracks, the GCPs and
    config.yaml (reconstruction.json, tracks.csv)."""
    import json

    from baarda.pipeline import read

    src = DATA / "opensfm_berlin"
    rec = json.loads((src / "reconstruction_example.json").read_text())
    keep = list(rec[0]["points"])[:40]
    rec[0]["points"] = {k: rec[0]["points"][k] for k in keep}
    kept = set(keep)
    rows = (src / "tracks_example.csv").read_text().splitlines()
    rows = rows[:1] + [r for r in rows[1:] if r.split("\t")[1] in kept]
    folder = work / "opensfm"
    folder.mkdir()
    (folder / "reconstruction.json").write_text(json.dumps(rec, indent=1))
    (folder / "tracks.csv").write_text("\n".join(rows) + "\n")
    for name in ("ground_control_points.json", "config.yaml"):
        (folder / name).write_bytes((src / name).read_bytes())
    kinds = {"reconstruction.json": "text", "tracks.csv": "text",
             "ground_control_points.json": "text", "config.yaml": "text"}
    return _checked(load_base(folder, kinds), work, "opensfm", read)
