"""`baarda adjust --gpkg`: the block as a GeoPackage (issue 14), opened with pyogrio."""

import numpy as np
import pandas as pd
import pytest

from baarda.cli import main

pyogrio = pytest.importorskip("pyogrio")


def test_geopackage_layers_counts_and_vectors(tmp_path):
    proj, out = tmp_path / "p", tmp_path / "o"
    assert main(["simulate", "-o", str(proj), "--pattern", "5", "--relief", "100",
                 "--blunders", "2", "--gnss", "0.05"]) == 0
    assert main(["adjust", str(proj), "-o", str(out), "--snoop", "--gpkg", "-q"]) == 0
    path = out / "block.gpkg"
    layers = dict(pyogrio.list_layers(path))
    assert layers == {"points": "Point Z", "projection_centres": "Point Z",
                      "image_residuals": "LineString"}
    pts = pd.read_csv(out / "points.csv", dtype={"point": str})
    obs = pd.read_csv(out / "observations.csv", keep_default_na=False, na_values=[""])
    img = obs[obs["kind"] == "image"]
    assert pyogrio.read_info(path, layer="points")["features"] == len(pts)
    assert pyogrio.read_info(path, layer="projection_centres")["features"] == 15
    info = pyogrio.read_info(path, layer="image_residuals")
    assert info["features"] == len(img) // 2 and info["crs"] is None
    _, _, geom, fields = pyogrio.raw.read(path, layer="image_residuals")
    names = list(info["fields"])
    table = pd.DataFrame({n: f for n, f in zip(names, fields, strict=True)})
    assert int(table["rejected"].sum()) >= 1  # the snooping's rejections are marked
    import shapely

    lines = shapely.from_wkb(geom)
    length = shapely.length(lines)
    v = np.hypot(table["vx_um"], table["vy_um"]) * 1e-3  # mm in the image
    # on the ground: v times distance / c (about 10 m per mm at 1:10,000), 1000 x
    ph = pd.read_csv(out / "photos.csv", dtype={"photo": str}).set_index("photo")
    xyz = pts.astype({"point": str}).set_index("point")[["X", "Y", "Z"]]
    centre = ph.loc[table["photo"], ["X0", "Y0", "Z0"]].to_numpy()
    dist = np.linalg.norm(xyz.loc[table["point"]].to_numpy() - centre, axis=1)
    exp = v * dist / 153.0 * 1000
    # the horizontal part of the turned vector: shorter by 1 - cos(tilt), < 1e-3 here
    assert np.allclose(length, exp, rtol=1e-3, atol=1e-6)
    assert 8 < np.median(dist / 153.0) < 12


def test_geopackage_in_the_projects_crs(tmp_path):
    from pathlib import Path

    data = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / \
        "micmac_ign_ultracam_aerial"
    if not data.is_dir():
        pytest.skip("../shared/data/micmac_ign_ultracam_aerial is not beside this checkout")
    out = tmp_path / "o"
    assert main(["adjust", str(data), "-o", str(out), "--gpkg", "-q"]) == 0
    for layer, n in (("points", 6463), ("projection_centres", 20), ("image_residuals", 18137)):
        info = pyogrio.read_info(out / "block.gpkg", layer=layer)
        assert info["features"] == n and info["crs"] == "EPSG:2154"
