"""AICON 3D Studio reader.  The example project is GPL-3.0 and is not copied into the
repository: the tests read it from ../shared/data/aicon_jaicov_closerange and skip, saying
so, when it is absent."""

import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from baarda.bundle.collinearity import project
from baarda.errors import ProjectError
from baarda.io.aicon import read_aicon
from baarda.output.format_files import write_aicon

SHARED = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / \
    "aicon_jaicov_closerange"
needs_data = pytest.mark.skipif(not (SHARED / "example.phc").is_file(),
                                reason=f"AICON example (GPL-3.0, not in the repository) not "
                                f"found at {SHARED}")


def _report_number(text: str, label: str) -> int:
    return int(re.search(re.escape(label) + r"\s*:\s*(\d+)", text).group(1))


@needs_data
def test_counts_equal_aicon_report():
    proj = read_aicon(SHARED / "example.phc")
    html = re.sub(r"<[^>]*>", " ", (SHARED / "example.htm").read_text(encoding="utf-8"))
    c = proj.counts()
    assert c["observations"] == _report_number(html, "Anzahl der Beobachtungen") == 19945
    assert c["points"] == _report_number(html, "Anzahl der geschätzten Objektpunkte") == 150
    assert c["images"] == _report_number(html, "Anzahl der verwendeten Bilder") == 115
    assert c["scale_bars"] == _report_number(html, "Anzahl der verwendeten Strecken") == 1
    block = proj.to_block()
    assert (len(block.photos), len(block.points), len(block.image)) == (115, 150, 9972)
    # "Minimale Anzahl von Strahlen: 5 in Bild 48"
    rays = np.bincount(block.image.photo, minlength=len(block.photos))
    m = re.search(r"Minimale Anzahl von Strahlen:\s*(\d+)\s+in Bild\s+(\d+)", html)
    assert rays.min() == int(m.group(1)) and block.photos.ids[int(np.argmin(rays))] == m.group(2)


@needs_data
def test_conventions_reproject_aicon_solution():
    """AICON's own EO and points reproject to within its lens distortion, which the
    residuals follow radially (A1, A2 with zero crossing R0)."""
    proj = read_aicon(SHARED)
    b = proj.to_block(sigma_image_mm=0.0005)
    im = b.image
    p = project(b.photos.eo[im.photo], b.points.xyz[im.point], b.cameras.focal_mm[0:1],
                b.cameras.principal_point_mm[0:1])
    d = im.xy_mm - p
    assert np.sqrt(np.mean(d**2)) < 0.05  # mm; the wrong sign of ck gives ~10 mm
    c = proj.cameras
    u = im.xy_mm - b.cameras.principal_point_mm[0]
    r = np.hypot(u[:, 0], u[:, 1])
    radial = np.sum(u * d, axis=1) / r
    model = c["A1"][0] * r * (r**2 - c["R0"][0] ** 2) + c["A2"][0] * r * (r**4 - c["R0"][0] ** 4)
    assert np.corrcoef(radial, model)[0, 1] > 0.99
    assert np.sqrt(np.mean((radial - model) ** 2)) < 0.005


@needs_data
def test_round_trip(tmp_path):
    proj = read_aicon(SHARED)
    write_aicon(proj, tmp_path)
    again = read_aicon(tmp_path / "example.eor")
    for part in ("cameras", "images", "points", "observations"):
        a, b = getattr(proj, part), getattr(again, part)
        for k in a:
            if k != "_lines":
                assert np.array_equal(a[k], b[k]), (part, k)
    assert list(again.scale_bars["name"]) == ["Scalebar"]
    assert again.counts() == proj.counts()


IOR = ("1 -999 -28.7 0.01 0.05 -1e-4 1e-7 13.4\n 0\n 5e-6 -8e-6\n -7e-5 -3e-5\n"
       " 35.9 23.9 8688 5792\n")
EOR = "1 1 100 200 300 0.1 0.2 0.3 0 307 3\n2 1 150 200 300 0.1 0.2 0.3 0 307 3\n"
OBC = "6 1 2 3 0.1 0.1 0.1 2 1 1 0\n"
PHC = "1 6 1.0 2.0 0.0005 0.0005 0 0 1 1 1\n2 6 1.5 2.0 0.0005 0.0005 0 0 1 1 1\n"
SCALE = '0 "bar" 6 7 1000.0 0.01 1\n'


def _project(tmp_path, **over):
    files = {"ior": IOR, "eor": EOR, "obc": OBC, "phc": PHC, "scale": SCALE}
    files.update(over)
    for ext, text in files.items():
        (tmp_path / f"t.{ext}").write_text(text)
    return tmp_path / "t.phc"


def test_minimal_project(tmp_path):
    proj = read_aicon(_project(tmp_path))
    assert proj.counts() == {"observations": 5, "image_points": 2, "scale_bars": 1,
                             "points": 1, "images": 2}
    b = proj.to_block()
    assert np.isclose(b.cameras.focal_mm[0], 28.7) and np.allclose(b.points.xyz[0],
                                                                    [1e-3, 2e-3, 3e-3])


def test_huge_sigmas_do_not_overflow(tmp_path):
    """Fuzz finds (issue 15: the mean square of sx and sy overflowed for sx = 1e200; later:
    a sigma beyond SIGMA_IMAGE_UM was named against the project, not its .phc line). It is
    refused at its line, without a numpy warning."""
    phc = PHC.replace("1.0 2.0 0.0005 0.0005", "1.0 2.0 1e200 1e200")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ProjectError, match=r"standard deviation 1e\+200 mm: expected "
                           r"1e-06 to 100 mm") as e:
            read_aicon(_project(tmp_path, phc=phc)).to_block()
    assert e.value.path.endswith("t.phc") and e.value.line == 1 and e.value.column == "sx"
    phc = PHC.replace("1.0 2.0 0.0005 0.0005", "1.0 2.0 0.0005 99.5")  # within: taken
    b = read_aicon(_project(tmp_path, phc=phc)).to_block()
    assert np.allclose(b.image.sigma_mm, [np.sqrt(0.5 * (0.0005**2 + 99.5**2)), 0.0005])


def test_no_active_observations(tmp_path):
    """Fuzz find (issue 15): a project without active observations gave a block with a NaN
    image sigma (the median of nothing, with numpy's RuntimeWarning)."""
    inactive = OBC.replace("2 1 1 0\n", "2 0 1 0\n")  # the point's status 0
    with pytest.raises(ProjectError, match="no active observations") as e:
        read_aicon(_project(tmp_path, obc=inactive)).to_block()
    assert e.value.path.endswith("t.phc")
    # an empty .obc is a file cut short (issue 41), refused naming it
    with pytest.raises(ProjectError, match="the file is empty") as e:
        read_aicon(_project(tmp_path, obc="")).to_block()
    assert e.value.path.endswith("t.obc")


@pytest.mark.parametrize("over, ext, line, column", [
    ({"phc": PHC.replace("1.0 2.0", "1.0 x")}, "phc", 1, "y"),
    ({"phc": PHC.replace(" 1 1 1\n2", " 1 1\n2")}, "phc", 1, None),
    ({"phc": PHC.replace("2 6 1.5", "9 6 1.5")}, "phc", 2, "image"),
    ({"phc": PHC.replace("0.0005 0.0005 0 0 1 1 1\n2", "-1 0.0005 0 0 1 1 1\n2")}, "phc", 1,
     "sx"),
    ({"eor": EOR.replace("2 1 150", "1 1 150")}, "eor", 2, "id"),
    ({"eor": EOR.replace("0.2 0.3 0 307 3\n2", "0.2 nan 0 307 3\n2")}, "eor", 1, "kappa"),
    ({"obc": OBC.replace("6 1 2 3", "6 1 2")}, "obc", 1, None),
    ({"ior": IOR.replace(" 0\n", " 0 1\n")}, "ior", 2, None),
    ({"scale": '0 bar 6 7 1000.0 0.01 1\n'}, "scale", 1, None),
    # fuzz find (issue 15): a form feed or U+2028 is no line end (the line numbers were off)
    ({"phc": "\x0c" + PHC.replace("2 6 1.5", "2 6 x")}, "phc", 2, "x"),
    ({"scale": '\u2028\n0 bar 6 7 1000.0 0.01 1\n'}, "scale", 2, None),
])
def test_malformed(tmp_path, over, ext, line, column):
    with pytest.raises(ProjectError) as e:
        read_aicon(_project(tmp_path, **over))
    assert e.value.path.endswith(f"t.{ext}") and e.value.line == line
    if column:
        assert e.value.column == column


@needs_data
def test_protocol_image_sigma_out_of_range_names_its_line(tmp_path):
    """An image sigma in the AICON protocol's 'Bildkoordinaten' table beyond SIGMA_IMAGE_UM
    (1 nm .. 100 mm) is refused at its line of the .htm (the protocol's sigmas replace the
    .phc's)."""
    from baarda.io.aicon_protocol import _ROW, read_protocol

    src = SHARED / "example.htm"
    raw = src.read_bytes()
    text = raw.decode("utf-8")
    lines = text.split("\n")
    start = next(i for i, t in enumerate(lines) if "Bildkoordinaten ***" in t)
    no = next(i for i in range(start + 2, len(lines)) if _ROW.match(lines[i].rstrip("\r")))
    m = _ROW.match(lines[no].rstrip("\r"))
    a, b = m.span(7)  # sx
    lines[no] = lines[no][:a] + "1e9" + lines[no][b:]
    bad = tmp_path / "example.htm"
    bad.write_bytes("\n".join(lines).encode("utf-8"))
    with pytest.raises(ProjectError, match=r"standard deviation 1e\+09 mm: expected 1e-06 "
                       r"to 100 mm") as e:
        read_protocol(bad)
    assert e.value.path == str(bad) and e.value.line == no + 1 and e.value.column == "sx"
    assert len(read_protocol(src).observations["sx"])  # the file as given reads
