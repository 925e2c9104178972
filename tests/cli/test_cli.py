"""The command line: simulate, adjust, snoop and their files."""

import json
from pathlib import Path

import numpy as np
import pandas as pd

from baarda.cli import main

DEMO = Path(__file__).parents[2] / "examples" / "demo"


def test_simulate_is_deterministic(tmp_path):
    args = ["simulate", "--strips", "2", "--photos", "4", "--blunders", "2", "--seed", "5"]
    assert main(args + ["-o", str(tmp_path / "a")]) == 0
    assert main(args + ["-o", str(tmp_path / "b")]) == 0
    for name in ("image_points.csv", "ground_points.csv", "photos.csv", "truth.json"):
        assert (tmp_path / "a" / name).read_text() == (tmp_path / "b" / name).read_text()
    truth = json.loads((tmp_path / "a" / "truth.json").read_text())
    assert len(truth["blunders"]) == 2
    assert {"photo", "point", "component", "size"} <= set(truth["blunders"][0])


def test_adjust_demo_with_snooping(tmp_path):
    out = tmp_path / "out"
    assert main(["adjust", str(DEMO), "-o", str(out), "--snoop", "-q"]) == 0
    s = json.loads((out / "summary.json").read_text())
    for key in ("sigma0", "redundancy", "n_observations", "n_unknowns", "iterations",
                "converged", "check_rms_X", "check_rms_Y", "check_rms_Z", "global_test",
                "n_rejected", "rejection_log"):
        assert key in s
    assert s["redundancy"] == s["n_observations"] - s["n_unknowns"]
    assert s["converged"]
    obs = pd.read_csv(out / "observations.csv", dtype={"photo": str, "point": str})
    assert len(obs) == s["n_observations"] + s["n_rejected"]
    assert np.isclose(obs.loc[~obs.rejected, "redundancy"].sum(), s["redundancy"], rtol=1e-9)
    truth = json.loads((DEMO / "truth.json").read_text())
    planted = {(b["photo"], str(b["point"]), b["component"]) for b in truth["blunders"]}
    rej = obs[obs.rejected]
    rejected = {(r.photo, r.point, r.component) for r in rej.itertuples()}
    # four of the five planted blunders are found, nothing else; the fifth sits in the y of a
    # two-ray point across strips, which no other observation controls (r = 0)
    assert len(rejected & planted) == 4 and rejected <= planted
    photos = pd.read_csv(out / "photos.csv")
    assert len(photos) == 32 and (photos.sigma_X0 > 0).all()
    points = pd.read_csv(out / "points.csv")
    assert {"X", "Y", "Z", "sigma_X", "sigma_Y", "sigma_Z"} <= set(points.columns)


def test_help_lists_commands(capsys):
    try:
        main(["--help"])
    except SystemExit:
        pass
    out = capsys.readouterr().out
    for cmd in ("adjust", "snoop", "simulate"):
        assert cmd in out


def test_version(capsys):
    from importlib.metadata import version

    import pytest

    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"baarda {version('baarda')}"


def test_every_option_has_help_with_its_default():
    """Every option of every command says what it does and, when it has one, its default."""
    import argparse

    from baarda.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    missing = []
    for name, p in sub.choices.items():
        text = p.format_help()
        for a in p._actions:
            if isinstance(a, argparse._HelpAction):
                continue
            flag = a.option_strings[0] if a.option_strings else a.dest
            if not a.help:
                missing.append(f"{name} {flag}: no help")
                continue
            d = a.default
            meaningful = d not in (None, False, [], argparse.SUPPRESS) and not (
                d is True and a.const is not None)
            formatted = p._get_formatter()._get_help_string(a) if meaningful else a.help
            if meaningful and "default" not in formatted:
                missing.append(f"{name} {flag}: default {d!r} not shown")
        assert "(default: " in text or name in ("online",), name
    assert not missing, "\n".join(missing)


def test_the_command_list_agrees_with_the_commands():
    """`baarda --help` names the commands without importing them (cli.COMMANDS): the
    module and one-line help of each must be those the module registers."""
    import argparse

    from baarda.cli import COMMANDS, build_parser

    full = build_parser()
    sub = next(a for a in full._actions if isinstance(a, argparse._SubParsersAction))
    helps = {a.dest: a.help for a in sub._choices_actions}
    assert set(sub.choices) == set(COMMANDS)
    for name, (_, text) in COMMANDS.items():
        assert helps[name] == text, name
    lazy = build_parser("")
    lazy_sub = next(a for a in lazy._actions if isinstance(a, argparse._SubParsersAction))
    assert list(lazy_sub.choices) == list(sub.choices)
    assert lazy.format_help() == full.format_help()
