"""Issue 33: `baarda online --bundle --watch DIR`: a reconstruction that grows on disk (COLMAP
snapshot folders of a simulated free network), each snapshot's new images tested against the
block before it, observations a later snapshot dropped taken out; the result folder of the
last state is `baarda adjust` of the last snapshot."""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from baarda.cli import main
from baarda.io.colmap import ColmapCamera, ColmapImages, ColmapModel, ColmapPoints
from baarda.io.colmap_block import eo_to_pose
from baarda.online.watch import Watch, snapshots, watch
from baarda.output.format_files import write_colmap
from baarda.simulate.aerial import FlightPlan, simulate_block

PM = 0.001  # mm per pixel (COLMAP's nominal 1 px = 1 µm)
W = H = 230_000  # the 230 mm format in pixels
BLUNDER_PX = 40.0  # 40 µm on a 1 µm image sigma


def moved_poses(poses, s: float, rot: np.ndarray, t: np.ndarray):
    """COLMAP poses (qvec w x y z, tvec) after the frame moves by X' = s rot X + t: the same
    image points (x_cam' = s x_cam = R rot^T X' + s t_c - R rot^T t)."""
    from scipy.spatial.transform import Rotation

    out = []
    for q, tc in poses:
        r = Rotation.from_quat([q[1], q[2], q[3], q[0]]).as_matrix() @ rot.T
        x, y, z, w = Rotation.from_matrix(r).as_quat()
        out.append((np.array([w, x, y, z]), s * np.asarray(tc) - r @ t))
    return out


def colmap_model(block, truth_xyz, photos, drop=(), blunder=None, move=None,
                 camera2=()) -> ColmapModel:
    """The COLMAP model of `photos` (indices) of a simulated block: their image points of
    the points seen at least twice among them, less the (photo, point) pairs in `drop`, with
    `blunder` ((photo, point), dx px) added; `move` (s, rot, t): in a frame moved by that
    similarity (a reconstruction's frame moves between snapshots)."""
    im = block.image
    sel = np.isin(im.photo, photos)
    sel &= ~np.array([(block.photos.ids[im.photo[r]], block.points.ids[im.point[r]]) in drop
                      for r in range(len(im))])
    rays = np.bincount(im.point[sel], minlength=len(block.points))
    sel &= rays[im.point] >= 2
    pid = {j: 1000 + j for j in np.unique(im.point[sel])}
    xys, p3d, tracks = [], [], {j: ([], []) for j in pid}
    for n, i in enumerate(photos):
        rows = np.flatnonzero(sel & (im.photo == i))
        xy = np.column_stack([im.xy_mm[rows, 0] / PM + W / 2, H / 2 - im.xy_mm[rows, 1] / PM])
        for k, r in enumerate(rows):
            key = (block.photos.ids[i], block.points.ids[im.point[r]])
            if blunder is not None and key == blunder[0]:
                xy[k, 0] += blunder[1]
            tracks[im.point[r]][0].append(n + 1)
            tracks[im.point[r]][1].append(k)
        xys.append(xy)
        p3d.append(np.array([pid[j] for j in im.point[rows]], np.int64))
    poses = [eo_to_pose(block.photos.eo[i]) for i in photos]
    xyz = truth_xyz + 0.3
    if move is not None:
        poses = moved_poses(poses, *move)
        xyz = move[0] * xyz @ move[1].T + move[2]
    images = ColmapImages.from_lists(
        np.arange(1, len(photos) + 1), [q for q, _ in poses], [t for _, t in poses],
        np.array([2 if i in camera2 else 1 for i in photos]),
        [f"{block.photos.ids[i]}.jpg" for i in photos], xys, p3d)
    js = sorted(pid)
    points = ColmapPoints.from_lists([pid[j] for j in js], xyz[js],
                                     np.zeros((len(js), 3)), np.zeros(len(js)),
                                     [tracks[j][0] for j in js], [tracks[j][1] for j in js])
    cam = ColmapCamera("SIMPLE_PINHOLE", W, H, np.array([153.0 / PM, W / 2, H / 2]))
    cams = {1: cam}
    if any(i in camera2 for i in photos):  # a second camera (the same interior orientation)
        cams[2] = ColmapCamera("SIMPLE_PINHOLE", W, H, np.array([153.0 / PM, W / 2, H / 2]))
    return ColmapModel(cams, images, points)


@pytest.fixture(scope="module")
def grown(tmp_path_factory):
    """DIR with four snapshots of a 12-photo free network (2 strips x 6): 6 photos, 8, 12
    with a blunder on a new photo, then the same 12 without the blunder's observation and
    one other (COLMAP's filtering)."""
    block, truth = simulate_block(FlightPlan(strips=2, photos_per_strip=6, pattern=5,
                                             control="none", height_chains=0, relief_m=30.0,
                                             sigma_image_um=1.0, seed=3))
    xyz = np.array([truth["points"][p] for p in block.points.ids], float)
    d = tmp_path_factory.mktemp("watch") / "sparse"
    order = list(range(12))
    im = block.image
    # the blunder: an image point on photo 10 whose point has four rays or more
    i10 = np.flatnonzero(im.photo == 10)
    rays = np.bincount(im.point, minlength=len(block.points))
    r = next(r for r in i10 if rays[im.point[r]] >= 4)
    bad = (block.photos.ids[10], block.points.ids[im.point[r]])
    r2 = next(r for r in np.flatnonzero(im.photo == 3) if rays[im.point[r]] >= 4)
    other = (block.photos.ids[3], block.points.ids[im.point[r2]])
    models = [colmap_model(block, xyz, order[:6]), colmap_model(block, xyz, order[:8]),
              colmap_model(block, xyz, order, blunder=(bad, BLUNDER_PX)),
              colmap_model(block, xyz, order, drop=(bad, other))]
    for n, m in enumerate(models, 1):
        write_colmap(m, d / f"{n:08d}")
    # the same growth, the frame moved from the third snapshot on (scale 1.02, 5 gon about
    # Z, 1 gon about X, 200 m east, 50 m south, 20 m up): the new photos' orientations come
    # into the block's frame by the similarity of what the snapshots have in common
    from scipy.spatial.transform import Rotation

    rot = Rotation.from_euler("zx", [0.0785, 0.0157]).as_matrix()
    move = (1.02, rot, np.array([200.0, -50.0, 20.0]))
    dm = d.parent / "moved"
    models = [*models[:2], colmap_model(block, xyz, order, blunder=(bad, BLUNDER_PX),
                                        move=move),
              colmap_model(block, xyz, order, drop=(bad, other), move=move)]
    for n, m in enumerate(models, 1):
        write_colmap(m, dm / f"{n:08d}")
    return d, bad, other, block, dm, xyz


def test_snapshots_in_order(grown):
    d = grown[0]
    assert [s.name for s in snapshots(d)] == ["00000001", "00000002", "00000003", "00000004"]
    assert [s.name for s in snapshots(d / "00000002")] == ["00000002"]  # in place


def watched_and_adjusted(d, last: str, tmp_path) -> tuple[dict, dict]:
    """`baarda online --bundle --watch D --once -o OUT` and `baarda adjust D/LAST -o REF`:
    their summary.json, after checking that redundancy and sigma0 agree (1e-8)."""
    out, ref = tmp_path / "out", tmp_path / "ref"
    assert main(["online", "--bundle", "--watch", str(d), "--once", "-o", str(out),
                 "-q"]) == 0
    assert main(["adjust", str(d / last), "-o", str(ref), "-q"]) == 0
    s = json.loads((out / "summary.json").read_text())
    s0 = json.loads((ref / "summary.json").read_text())
    assert s["redundancy"] == s0["redundancy"]
    assert s["sigma0"] == pytest.approx(s0["sigma0"], rel=1e-8)
    return s, s0


@pytest.mark.parametrize("frame", ["fixed", "moved"])
def test_watch_once_flags_the_blunder_and_ends_as_adjust(grown, tmp_path, frame):
    d, bad = grown[4] if frame == "moved" else grown[0], grown[1]
    out, ref = tmp_path / "out", tmp_path / "ref"
    s, s0 = watched_and_adjusted(d, "00000004", tmp_path)
    assert s["sum_redundancy_numbers"] == pytest.approx(s0["sum_redundancy_numbers"],
                                                        rel=1e-8)
    o, o0 = (pd.read_csv(p / "observations.csv") for p in (out, ref))
    key = ["kind", "photo", "point", "component"]
    both = o.merge(o0, on=key, suffixes=("", "_ref"))
    assert len(both) == len(o) == len(o0)
    assert np.allclose(both["redundancy"], both["redundancy_ref"], atol=1e-8)
    t = pd.read_csv(out / "watch.csv", dtype={"photo": str, "point": str})
    assert list(t.columns[:2]) == ["snapshot", "step"]
    pt = str(1000 + grown[3].points.ids.index(bad[1]))
    row = t[(t.photo == bad[0]) & (t.point == pt) & (t.component == "x")]
    assert list(row.snapshot) == [3]  # tested once: when it arrived
    assert list(row.verdict) == ["reject"]
    # the snapshot's other new image points: a few accepted at least
    s3 = t[(t.snapshot == 3)]
    assert (s3.verdict == "accept").sum() > 50
    tested = t[t.row == "test"]
    assert set(tested.snapshot) == {1, 2, 3}  # snapshot 4 only took observations out
    # the verdicts its removals changed are rows too (issue 41)
    changed = t[t.row == "change"]
    assert 4 in set(changed.snapshot) and (changed.before != changed.verdict).all()


def test_watch_api_retries_a_half_written_snapshot(grown, tmp_path):
    """A snapshot whose points3D.txt is not there yet is left for the next poll; the one
    after it waits too (order); a malformed one fails after the retries, naming the file."""
    d = tmp_path / "grow"
    src = grown[0]
    for n in (1, 2):
        (d / f"{n:08d}").mkdir(parents=True)
        for f in (src / f"{n:08d}").iterdir():
            (d / f"{n:08d}" / f.name).write_bytes(f.read_bytes())
    (d / "00000002" / "points3D.txt").unlink()
    (d / "00000003").mkdir()
    for f in (src / "00000003").iterdir():
        (d / "00000003" / f.name).write_bytes(f.read_bytes())
    w = Watch(d)
    assert w.poll() == 1 and w.done == ["00000001"] and w.waiting == ["00000002"]
    assert w.poll() == 0 and w.done == ["00000001"]
    (d / "00000002" / "points3D.txt").write_bytes((src / "00000002" / "points3D.txt")
                                                  .read_bytes())
    assert w.poll() == 2 and w.done == ["00000001", "00000002", "00000003"]
    assert not w.waiting
    assert w.online.started and len(w.table()) > 0
    # a malformed snapshot: an error after RETRIES polls, naming its file
    (d / "00000004").mkdir()
    for f in (src / "00000004").iterdir():
        (d / "00000004" / f.name).write_bytes(f.read_bytes())
    (d / "00000004" / "images.txt").write_text("# broken\n1 2 3\n")
    assert w.poll() == 0 and w.poll() == 0
    with pytest.raises(Exception, match="images.txt"):
        w.poll()


def test_watch_exit_codes(grown, tmp_path, capsys):
    d = tmp_path / "bad"
    (d / "00000001").mkdir(parents=True)
    (d / "00000001" / "cameras.txt").write_text("1 SIMPLE_PINHOLE 10 10 nonsense\n")
    (d / "00000001" / "images.txt").write_text("")
    (d / "00000001" / "points3D.txt").write_text("")
    assert main(["online", "--bundle", "--watch", str(d), "--once", "--interval", "0.01",
                 "-o", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "cameras.txt" in err
    assert not (tmp_path / "o").exists()
    assert main(["online", "--bundle", "--watch", str(grown[0]), "--once"]) == 2  # no -o
    assert main(["online", "--bundle", "--watch", str(tmp_path / "none"), "--once", "-o",
                 str(tmp_path / "o2")]) == 2
    assert main(["online", "--bundle", "--once", "-o", str(tmp_path / "o3")]) == 2
    inside = grown[0] / "00000009"  # OUT inside DIR would be read as a snapshot
    assert main(["online", "--bundle", "--watch", str(grown[0]), "--once", "-o",
                 str(inside)]) == 2
    assert not inside.exists()


def test_watch_interrupted_writes_what_is_complete(grown, tmp_path, monkeypatch):
    """Ctrl-C while waiting for the next snapshot: exit 130, the result folder of the
    snapshots taken in."""
    import baarda.online.watch as wmod

    calls = []

    def sleep(s):
        calls.append(s)
        raise KeyboardInterrupt

    monkeypatch.setattr(wmod.time, "sleep", sleep)
    d = tmp_path / "g"
    (d / "00000001").mkdir(parents=True)
    for f in (grown[0] / "00000001").iterdir():
        (d / "00000001" / f.name).write_bytes(f.read_bytes())
    out = tmp_path / "out"
    assert main(["online", "--bundle", "--watch", str(d), "-o", str(out), "-q"]) == 130
    assert calls and (out / "summary.json").is_file()
    t = pd.read_csv(out / "watch.csv")
    assert set(t.snapshot) == {1}
    assert Path(out / "observations.csv").is_file()


def test_watch_a_model_rewritten_in_place(grown, tmp_path):
    """One COLMAP folder rewritten in place: a new snapshot each time its files change,
    none while they stay the same."""
    import os

    src, d = grown[0], tmp_path / "sparse"
    d.mkdir()

    def write(n, stamp):
        for f in (src / f"{n:08d}").iterdir():
            (d / f.name).write_bytes(f.read_bytes())
            os.utime(d / f.name, ns=(stamp, stamp))

    write(1, 1_000_000_000)
    w = Watch(d)
    assert w.poll() == 1 and w.done == ["sparse#1"]
    assert w.poll() == 0
    write(2, 2_000_000_000)
    assert w.poll() == 1 and w.done == ["sparse#1", "sparse#2"]
    t = w.table()
    assert set(t.snapshot) == {"sparse#1", "sparse#2"}
    assert (t[t.snapshot == "sparse#2"].photo.isin(["01007", "01008", "02001",
                                                   "02002"])).any()


def test_watch_function_once(grown):
    """The API's one call (`baarda.online.watch.watch`): every snapshot taken in, in order,
    each answer passed to `progress`, the blunder rejected at snapshot 3."""
    seen = []
    w = watch(grown[0], once=True, interval=0.0,
              progress=lambda name, answer: seen.append(name))
    assert w.done == ["00000001", "00000002", "00000003", "00000004"]
    assert set(seen) >= {"00000001", "00000002", "00000003"}
    t = w.table()
    bad = grown[1]
    pt = str(1000 + grown[3].points.ids.index(bad[1]))
    row = t[(t.photo == bad[0]) & (t.point == pt) & (t.component == "x")]
    assert list(row.verdict) == ["reject"] and list(row.snapshot) == ["00000003"]


def test_a_new_camera_in_a_later_snapshot(grown, tmp_path):
    """The photos of the second strip taken with a second camera that the first snapshots
    do not have (COLMAP gives each camera of a run its own id): the camera is added with
    them, and the end equals `baarda adjust` of the last snapshot."""
    block, xyz = grown[3], grown[5]
    d = tmp_path / "sparse"
    order = list(range(12))
    second = set(range(6, 12))
    for n, photos in enumerate((order[:6], order[:9], order), 1):
        write_colmap(colmap_model(block, xyz, photos, camera2=second), d / f"{n:08d}")
    watched_and_adjusted(d, "00000003", tmp_path)
    w = pd.read_csv(tmp_path / "out" / "watch.csv", dtype={"snapshot": str, "photo": str})
    assert set(w.loc[w["snapshot"] == "00000002", "photo"]) >= {"02001", "02002", "02003"}
    said = []
    watch(d, once=True, interval=0.0, progress=lambda snap, a: said.append((snap, a)))
    assert [(snap, a.what) for snap, a in said if a.action == "camera"] == [
        ("00000002", "camera 2")]
    assert said[-1][1].tested and all(t.verdict != "reject" for _, a in said
                                      for t in a.tested)
