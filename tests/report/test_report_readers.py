"""Post-processor inputs: generic CSV, PhotoModeler's 2D point table, observations.csv."""

import re
from pathlib import Path

import numpy as np
import pytest

from baarda.cli import main
from baarda.errors import ProjectError
from baarda.io.residual_listings import detect, read_residuals
from baarda.report.stats import group_statistics, vector_statistics

PM = Path(__file__).parents[1] / "data" / "dbat_sxb_photomodeler"
PM_FILES = [PM / "wsmart-no-orient-2dpts.txt", PM / "wsmart-no-orient-2dsmartpts.txt"]


def pm_reference() -> tuple[float, float, str, str]:
    """PhotoModeler's own 'Point Marking Residuals': overall RMS, maximum and where (px)."""
    text = (PM / "wsmart-no-orient-pmreport.txt").read_text(errors="replace")
    rms = float(re.search(r"Overall RMS: ([\d.]+) pixels", text).group(1))
    m = re.search(r"Maximum: ([\d.]+) pixels\s+Point (\S+) on Photo (\S+)", text)
    return rms, float(m.group(1)), m.group(2), m.group(3)


def test_photomodeler_reproduces_its_own_summary():
    rs = read_residuals(PM_FILES)
    assert rs.units["image"] == "px"
    assert (rs.obs["kind"] == "image").sum() == 2 * 1196  # 47 marks + 1149 tie observations
    v = vector_statistics(rs.obs, "px")
    rms, vmax, point, photo = pm_reference()
    assert v.count == 1196
    assert round(v.rms, 3) == rms  # 1.097 px
    assert round(v.maximum, 3) == vmax  # 3.124 px
    assert v.max_at == f"photo {photo} point {point}"  # point 410 on photo 5


def test_photomodeler_pixel_size_and_cli(capsys):
    px = read_residuals(PM_FILES)
    um = read_residuals(PM_FILES, pixel_size_um=6.0)
    assert um.units["image"] == "µm"
    np.testing.assert_allclose(um.obs["residual"], 6.0 * px.obs["residual"])
    first = um.obs.iloc[0]  # 317,1,...,-1.831441,0.775775
    assert (first["point"], first["photo"], first["component"]) == ("317", "1", "x")
    assert first["residual"] == pytest.approx(-1.831441 * 6)
    assert main(["residuals", *map(str, PM_FILES), "--pixel-size", "6"]) == 0
    out = capsys.readouterr().out
    assert "IMAGE X AND Y RESIDUALS  (classes of 1 µm; n = 2392" in out
    assert re.search(r"image vector\s+µm\s+1196\s+\S+\s+6\.58", out)  # 1.097 px * 6 µm
    assert main(["residuals", *map(str, PM_FILES)]) == 0
    assert "classes of 0.1 px" in capsys.readouterr().out


def test_photomodeler_crlf_and_bad_value(tmp_path):
    head = ("Project Units: meters\r\r\nx\r\r\n\r\r\nObject Point ID,Photo #,X (pixels),"
            "Y (pixels),Residual X,Residual Y,Residual Vector,Mark Type,Layer,Material,"
            "Tagged\r\r\n")
    ok = "7,2,1.0,2.0,0.5,-0.25,0.559,SmartPoint,Default,White, \r\r\n"
    f = tmp_path / "pm.txt"
    f.write_text(head + ok + ok.replace("7,2", "8,3"), newline="")
    assert detect(f) == "photomodeler"
    rs = read_residuals([f])
    assert list(rs.obs["residual"]) == [0.5, -0.25, 0.5, -0.25]
    assert list(rs.obs["line"]) == [5, 5, 6, 6]
    f.write_text(head + ok + ok.replace("0.5,", "abc,", 1), newline="")
    with pytest.raises(ProjectError, match=r"pm.txt, line 6, column 'Residual X'.*'abc'"):
        read_residuals([f])


def test_generic_errors_name_file_line_column(tmp_path):
    f = tmp_path / "img.csv"
    f.write_text("# residuals in µm\npoint,photo,vx,vy\n1,a,1.5,2\n2,a,x1,3\n")
    with pytest.raises(ProjectError, match=r"img.csv, line 4, column 'vx'.*'x1'"):
        read_residuals([f])
    f.write_text("point,photo,vx,vy\n1,a,1.5,\n")
    with pytest.raises(ProjectError, match=r"line 2, column 'vy'"):
        read_residuals([f])
    f.write_text("id,dx,dy\n1,2,3\n")
    with pytest.raises(ProjectError, match=r"line 1: unknown residual listing"):
        read_residuals([f])
    g = tmp_path / "ctl.csv"
    g.write_text("point,vX,vY,vZ\n1,,,\n")
    with pytest.raises(ProjectError, match=r"ctl.csv, line 2.*no residual"):
        read_residuals([g])
    assert main(["residuals", str(f)]) == 2


def test_generic_image_with_strip_and_mixing_units(tmp_path, capsys):
    f = tmp_path / "img.csv"
    f.write_text("point,photo,vx,vy,strip\n1,a,3,-4,S1\n2,b,-1,2,S2\n")
    rs = read_residuals([f])
    g = {s.name: s for s in group_statistics(rs.obs, rs.units)}
    assert g["image x"].rms == pytest.approx(np.sqrt(5.0))
    assert main(["residuals", str(f)]) == 0
    out = capsys.readouterr().out
    assert "PER STRIP" in out and re.search(r"^S1\s+1\s+3\.00\s+-4\.00", out, re.M)
    with pytest.raises(ProjectError, match="cannot be mixed"):
        read_residuals([f, PM_FILES[0]])


def test_reads_baarda_observations(tmp_path):
    f = tmp_path / "observations.csv"
    f.write_text("kind,photo,point,component,residual,rejected\nimage,p,1,x,2.0,False\n"
                 "image,p,1,y,-2.0,False\nimage,p,2,x,50,True\nimage,p,2,y,1,True\n"
                 "control,,9,Z,0.1,False\n")
    rs = read_residuals([f])
    g = {s.name: s for s in group_statistics(rs.obs, rs.units)}
    assert g["image x"].count == 1 and g["image x"].rejected == 1
    assert g["control Z"].maximum == 0.1
