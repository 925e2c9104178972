"""Every option validated where it is parsed: exit 2 with the option and its valid range, no
traceback, nothing written (issue 29: each reproduction of its fault run)."""

import json
import shutil
from pathlib import Path

import pytest

from baarda.cli import main
from baarda.cli.argtypes import integer, number

ROOT = Path(__file__).parents[2]
DEMO = ROOT / "examples" / "demo"
STRIP = ROOT / "examples" / "online" / "strip.txt"


@pytest.mark.parametrize("argv, message", [
    (["simulate", "--strips", "0"], "argument --strips: an integer from 1 to 500, not '0'"),
    (["plan", "--strips", "0"], "argument --strips: an integer from 1 to 500, not '0'"),
    (["plan", "--side-overlap", "1.0", "--scale", "-5"],
     "argument --side-overlap: a number in [0, 1), not '1.0'"),
    (["plan", "--scale", "-5"], "argument --scale: a number in [1, 1e+07], not '-5'"),
    (["simulate", "--pattern", "1"], "argument --pattern: an integer from 2 to 25, not '1'"),
    (["plan", "--pattern", "0"], "argument --pattern: an integer from 2 to 25, not '0'"),
    (["pattern", "zz;;--"], "argument spec: one of 6, 9, 10, 12, 15, 13, CxR, CxR+corners or "
     "CxR+edges (2 to 20 columns and rows), or a CSV file, not 'zz;;--'"),
    (["adjust", "DEMO", "--screen", "--pair-alpha0", "0"],
     "argument --pair-alpha0: a number in [1e-12, 0.5), not '0'"),
    (["adjust", "DEMO", "--screen", "--stages", "9"],
     "argument --stages: a comma list of stages from 1, 2, 3, not '9'"),
    (["online", "STRIP", "--focal", "0"],
     "argument --focal: a number in [1, 10000] mm, not '0'"),
    (["evaluate", "--workers", "0"], "argument --workers: an integer from 1 to 1024, not '0'"),
    (["report", "OUT", "--text", "--exaggeration", "nan"],
     "argument --exaggeration: a number in (0, 1e+09], not 'nan'"),
    (["simulate", "--blunder-size", "5", "1"],
     "argument --blunder-size: MIN must be <= MAX, not 5 1"),
    (["simulate", "--seed", "-1"],
     "argument --seed: an integer from 0 to 9223372036854775807, not '-1'"),
    (["adjust", "DEMO", "--alpha0", "1e-300"],
     "argument --alpha0: a number in [1e-12, 0.5), not '1e-300'"),
    (["adjust", "DEMO", "--beta0", "inf"], "argument --beta0: a number in [0.5, 0.99999], "
     "not 'inf'"),
    (["models", "DEMO", "--deformations", "warp"],
     "argument --deformations: a comma list of deformations from "),
    (["evaluate", "--scheduler", "nowhere"],
     "argument --scheduler: an address PROTOCOL://HOST:PORT, e.g. tcp://host:8786"),
    (["report", "OUT", "--text", "--range", "5", "5"],
     "argument --range: LO must be < HI, not 5 5"),
])
def test_a_bad_option_value_is_exit_2_naming_the_option_and_its_range(tmp_path, capsys, argv,
                                                                         message):
    out = tmp_path / "out"
    if "OUT" in argv:
        assert main(["adjust", str(DEMO), "-o", str(out), "-qq"]) == 0
    argv = [{"DEMO": str(DEMO), "STRIP": str(STRIP), "OUT": str(out)}.get(a, a) for a in argv]
    if argv[0] in ("simulate", "plan", "evaluate", "adjust", "models"):
        argv += ["-o", str(tmp_path / "new")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err, err
    assert "Traceback" not in err
    assert not (tmp_path / "new").exists()


def test_the_types_name_their_range():
    import argparse

    with pytest.raises(argparse.ArgumentTypeError, match=r"an integer from 2 to 5, not '6'"):
        integer(2, 5)("6")
    with pytest.raises(argparse.ArgumentTypeError, match=r"a number in \(0, 1\) m, not '1'"):
        number(0, 1, lo_open=True, hi_open=True, unit="m")("1")
    assert number(0, 1)("1") == 1.0 and integer(0)(" 7") == 7
    for bad in ("nan", "inf", "-inf", "1e309", "", "x"):
        with pytest.raises(argparse.ArgumentTypeError):
            number()(bad)


def test_more_blunders_than_observations_is_refused(tmp_path, capsys):
    """`simulate --blunders 100000` planted 100,000 blunders into 125 image points."""
    assert main(["simulate", "-o", str(tmp_path / "s"), "--blunders", "100000"]) == 2
    assert ("baarda: error: --blunders: 100000 blunders asked for, but the block has 250 "
            "observations of the kinds x, y (at most one blunder in each)") in \
        capsys.readouterr().err
    assert not (tmp_path / "s").exists()
    assert main(["simulate", "-o", str(tmp_path / "s"), "--blunders", "250", "--strips", "3",
                 "--photos", "5", "--seed", "4"]) == 0
    truth = json.loads((tmp_path / "s" / "truth.json").read_text())
    planted = {(b["photo"], b["point"], b["component"]) for b in truth["blunders"]}
    assert len(planted) == 250  # every observation once
    assert main(["simulate", "-o", str(tmp_path / "c"), "--blunders", "1", "--blunder-kinds",
                 "X", "--control", "none", "--height-chains", "0"]) == 2
    assert "the block has 0 observations of the kinds X" in capsys.readouterr().err


def test_fewer_check_points_than_asked_for_is_said(tmp_path, capsys):
    """`simulate --check-points 12` on a block with 9 interior tie points gave 9 silently."""
    assert main(["simulate", "-o", str(tmp_path / "s"), "--strips", "2", "--photos", "3",
                 "--check-points", "12"]) == 0
    cap = capsys.readouterr()
    assert ("note: 12 check points asked for, but the block has only 9 interior tie points: "
            "9 check points") in cap.err
    assert "(4 control, 9 check, 4 tie)" in cap.out


def test_a_failed_online_run_leaves_no_output_folder(tmp_path, capsys):
    """`online` with inf values left an empty output folder (the folder of -o was made
    before the work)."""
    bad = tmp_path / "bad.txt"
    bad.write_text(STRIP.read_text().replace("0.000000 90.145125", "inf 90.145125", 1))
    out = tmp_path / "new" / "c.csv"
    assert main(["online", str(bad), "-o", str(out)]) == 2
    assert f"{bad}, line " in capsys.readouterr().err
    assert not (tmp_path / "new").exists()
    assert main(["online", str(STRIP), "--sigma", "inf", "-o", str(out)]) == 2
    assert not (tmp_path / "new").exists()
    assert main(["online", str(STRIP), "-o", str(out)]) == 0
    assert out.is_file()  # the folder is made when the file is written


def test_online_refuses_an_output_place_that_takes_no_files(tmp_path, capsys):
    assert main(["online", str(STRIP), "-o", "/proc/c.csv"]) == 2
    assert "/proc: cannot write a file here" in capsys.readouterr().err


def test_plan_derive_table_needs_a_flight_plan(tmp_path, capsys):
    shutil.copytree(DEMO, tmp_path / "p")
    assert main(["plan", "--project", str(tmp_path / "p"), "-o", str(tmp_path / "o"),
                 "--derive-table", str(tmp_path / "t.csv"), "-q"]) == 2
    assert "--derive-table: needs a flight plan, not --project" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_evaluate_says_when_trials_planted_fewer_blunders(tmp_path, capsys):
    assert main(["evaluate", "-o", str(tmp_path / "e"), "--trials", "1", "--strips", "2",
                 "--photos", "3", "--blunders", "100000", "--strategies", "snoop",
                 "-q"]) == 0
    err = capsys.readouterr().err
    assert "baarda: warning: --blunders 100000: some trials planted only " in err
    assert err.splitlines()[-1].startswith("baarda evaluate: 1 trials of 1 strategy -> ")


def test_pattern_ties_that_the_pattern_has_not(capsys):
    assert main(["pattern", "6", "--ties", "5"]) == 2
    assert ("baarda: error: --ties: pattern '6' has 3 points in the left column, not 5 tie "
            "points") in capsys.readouterr().err
