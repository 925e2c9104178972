"""The newcomer friction of issue 15: what the program prints says what it did."""

import io
import json
import sys
from pathlib import Path

import pandas as pd
import pytest

from baarda.cli import main

ROOT = Path(__file__).parents[2]
DEMO = ROOT / "examples" / "demo"


def test_tau_snooping_says_tau(tmp_path, capsys):
    assert main(["adjust", str(DEMO), "-o", str(tmp_path / "o"), "--snoop", "--tau"]) == 0
    out = capsys.readouterr().out
    assert "data snooping with Pope's tau (sigma0 a posteriori), critical |tau| " in out
    steps = [ln for ln in out.splitlines() if " reject " in ln]
    assert steps and all(" tau = " in ln and " w = " not in ln for ln in steps)
    log = json.loads((tmp_path / "o" / "summary.json").read_text())["rejection_log"]
    assert {s["statistic"] for s in log} == {"tau"}


def test_robust_snooping_lists_every_rejection(tmp_path, capsys):
    assert main(["adjust", str(DEMO), "-o", str(tmp_path / "o"), "--snoop", "--robust"]) == 0
    out = capsys.readouterr().out
    head = next(ln for ln in out.splitlines() if ln.startswith("data snooping with"))
    assert "3 rejected by the Danish method first, 1 step(s), 4 rejected in the end" in head
    steps = [ln for ln in out.splitlines() if " reject " in ln]
    assert len(steps) == 4 and sum("by the Danish method (w = " in ln for ln in steps) == 3
    obs = pd.read_csv(tmp_path / "o" / "observations.csv")
    assert int(obs["rejected"].sum()) == 4


def test_rejection_log_mdb_in_the_units_of_observations_csv(tmp_path):
    assert main(["adjust", str(DEMO), "-o", str(tmp_path / "o"), "--snoop", "-q"]) == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    obs = pd.read_csv(tmp_path / "o" / "observations.csv", dtype={"photo": str, "point": str})
    first = s["rejection_log"][0]
    kind, _, photo, _, point, comp = first["observations"][0].split()
    row = obs[(obs.kind == kind) & (obs.photo == photo) & (obs.point == point)
              & (obs.component == comp)]
    assert len(row) == 1 and row["rejected"].item()
    # the MDB when it was rejected and in the final adjustment: the same size and unit
    assert first["mdb_unit"] == "µm"
    assert 0.5 < first["mdb"] / row["mdb"].item() < 2


@pytest.mark.slow
def test_counts_say_what_was_left_out(tmp_path, capsys):
    assert main(["adjust", str(DEMO), "-o", str(tmp_path / "o"), "--snoop"]) == 0
    out = capsys.readouterr().out
    assert "observations 594 (4 rejected component(s) left out), unknowns 426" in out
    assert main(["report", str(tmp_path / "o"), "-o", str(tmp_path / "r.html")]) == 0
    err = capsys.readouterr().err
    assert "598 observation components, 594 used and 4 rejected" in err


def test_convert_over_an_earlier_project_replaces_it_whole(tmp_path, capsys):
    proj = tmp_path / "p"
    assert main(["simulate", "-o", str(proj), "--seed", "1"]) == 0
    assert (proj / "truth.json").exists()
    capsys.readouterr()
    assert main(["convert", str(DEMO), "-o", str(proj)]) == 0
    assert "(replacing run " in capsys.readouterr().out
    assert not (proj / "truth.json").exists()  # nothing of the earlier project is left


def test_online_example_and_empty_stdin(tmp_path, capsys, monkeypatch):
    assert main(["online", str(ROOT / "examples" / "online" / "strip.txt"), "-o",
                 str(tmp_path / "c.csv")]) == 0
    out = capsys.readouterr().out
    assert "REMEASURE POINT 31 (y'': SIGF 7.90 > 3.29)" in out
    assert "model 3-4 accepted: 21 points in the strip" in out
    monkeypatch.setattr(sys, "stdin", io.StringIO(""))
    assert main(["online"]) == 2
    assert "<stdin>: no measurements: give a measurement file" in capsys.readouterr().err
