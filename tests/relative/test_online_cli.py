"""`baarda online` and `baarda pattern` end to end."""

import io
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from baarda.cli import main
from baarda.relative.point_pattern import design, standard_pattern
from baarda.simulate.online_strip import online_text, simulate_strip


def _blunder_file(tmp_path, point="31", dy=0.100):
    st = simulate_strip(3, "9", sigma_x=5.0, seed=1, attitude=0.02)
    lines = online_text(st, 152.0, 5.0).splitlines()
    m = lines.index("model 2-3")
    i = next(k for k in range(m, len(lines)) if lines[k].startswith(point + " "))
    good = lines[i]
    f = good.split()
    f[4] = f"{float(f[4]) + dy:.6f}"
    lines[i] = " ".join(f)
    end = lines.index("end", m)
    lines[end + 1:end + 1] = ["remeasure " + good, "accept"]
    path = tmp_path / "strip.txt"
    path.write_text("\n".join(lines) + "\n")
    return path, st


def test_online_file_flags_and_remeasures(tmp_path, capsys):
    path, st = _blunder_file(tmp_path)
    out_csv = tmp_path / "coords.csv"
    assert main(["online", str(path), "-o", str(out_csv)]) == 0
    out = capsys.readouterr().out
    first, after = out.split("remeasured point 31")
    model2 = first[first.index("MODEL 2-3"):]
    assert "REMEASURE POINT 31 (y''" in model2
    row = next(ln for ln in after.splitlines() if ln.split()[:2] == ["31", "y"])
    assert float(row.split()[5]) < 3.29  # SIGF after remeasuring
    assert "model 2-3 accepted" in out and "model 3-4 accepted" in out  # last one at EOF
    rows = out_csv.read_text().splitlines()
    assert rows[0] == "point,X,Y,Z,model" and len(rows) == 1 + len(st.points)


def test_online_reads_stdin(monkeypatch, capsys):
    st = simulate_strip(2, "6", sigma_x=5.0, seed=3)
    text = online_text(st, 152.0, 5.0).replace("camera focal=152 sigma=5\n", "")
    monkeypatch.setattr(sys, "stdin", io.StringIO(text + "coords\n"))
    assert main(["online", "--focal", "152", "--sigma", "5"]) == 0
    out = capsys.readouterr().out
    assert out.count("MODEL ") == 2 and "  21 " in out


def test_online_prompt_keeps_going_after_errors(monkeypatch, capsys):
    st = simulate_strip(1, "6", sigma_x=5.0, seed=3)
    lines = online_text(st, 152.0, 5.0).splitlines()[1:]
    feed = iter(["nonsense"] + lines + ["drop 99", "drop 12", "matrix", "help", "quit"])

    def fake_input(prompt=""):
        try:
            return next(feed)
        except StopIteration:
            raise EOFError from None

    monkeypatch.setattr(sys.stdin, "isatty", lambda: True, raising=False)
    monkeypatch.setattr("builtins.input", fake_input)
    assert main(["online"]) == 0
    out = capsys.readouterr().out
    assert "error: unknown command 'nonsense'" in out
    assert "error: point 99 is not in model 1-2" in out
    assert "error: model 1-2: 5 points and 0 tie points give no redundancy" in out
    assert "remeasure ID x' y' x'' y''" in out  # help
    assert "Qvv P (column: error in; row: shows at)" in out and "    12y" in out
    assert "model 1-2 accepted: 6 points" in out  # the failed drop left the model as it was


@pytest.mark.parametrize("text,where", [
    ("camera focal=152\nmodel 1-2\n11 0 0 x 1\nend\n", "line 3, column 'x''"),
    ("camera focal=152\nbogus\n", "line 2, column 'command'"),
    ("model 1-2\n", "line 1, column 'focal'"),
    ("camera focal=152\nmodel 1-2\n11 0 0 -90 1\n", "line 3, column 'end'"),
    ("camera focal=152\nmodel 1-2\n11 0 0 -90 1\n12 0 1 -90 2\nend\n", "line 5: model 1-2"),
    ("camera focal=-1\n", "line 1, column 'focal'"),
])
def test_online_bad_input_names_file_and_line(tmp_path, capsys, text, where):
    path = tmp_path / "bad.txt"
    path.write_text(text)
    assert main(["online", str(path), "-o", str(tmp_path / "c.csv")]) == 2
    err = capsys.readouterr().err
    assert f"{path}, {where}" in err
    assert not (tmp_path / "c.csv").exists()


def test_pattern_text_and_svg(tmp_path, capsys):
    svg = tmp_path / "p.svg"
    assert main(["pattern", "9", "--ties", "3", "--svg", str(svg), "--matrix"]) == 0
    out = capsys.readouterr().out
    assert "r0 = 0.500 = (n-3)/(n+3)" in out
    assert "1x -> 2x" in out and "Qvv P" in out
    d = design(standard_pattern("9", 3))
    root = ET.parse(svg).getroot()
    ns = "{http://www.w3.org/2000/svg}"
    crit = [e for e in root.iter(ns + "line") if e.get("class") == "critical"]
    distinct = [t for t in d.transfers
                if d.orientation.obs_point[t.source] != d.orientation.obs_point[t.target]]
    assert len(crit) == len(distinct) == 4
    assert len([e for e in root.iter(ns + "rect") if e.get("class") == "tie"]) == 3


def test_pattern_from_csv_and_its_errors(tmp_path, capsys):
    good = tmp_path / "pts.csv"
    good.write_text("name,x,y,tie\n" + "".join(
        f"{n},{x},{y},{int(x == 0)}\n" for n, (x, y) in
        enumerate([(0, 90), (0, 0), (0, -90), (92, 90), (92, 0), (92, -90), (46, 45)], 1)))
    assert main(["pattern", str(good)]) == 0
    out = capsys.readouterr().out
    assert "7 points, 3 tie points -> 10 observations" in out
    bad = tmp_path / "bad.csv"
    bad.write_text("name,x,y\n1,0,90\n2,zero,0\n")
    assert main(["pattern", str(bad)]) == 2
    assert f"{bad}, line 3, column 'x'" in capsys.readouterr().err


def test_pattern_rejects_unknown_and_mismatched_ties(capsys):
    with pytest.raises(ValueError, match="unknown pattern"):
        standard_pattern("7")
    with pytest.raises(ValueError, match="not 5 tie points"):
        standard_pattern("9", 5)
    assert np.isclose(design(standard_pattern("6")).r0, 1 / 6)
