"""Blocks the on-line bundle does not take: refused before the first step (exit 2)."""

import pytest

from baarda.cli import main


@pytest.mark.parametrize("offsets", ["strip", "block"])
def test_replay_refuses_gnss_shifts_at_the_start(offsets, tmp_path, capsys):
    """GNSS shifts are unknowns of the whole block, which the on-line bundle does not
    estimate (docs/online.md, "Not done"): exit 2 before the first step, the setting named
    and `baarda adjust` offered (it was a ValueError traceback from the replay's start)."""
    project = tmp_path / "gnss"
    assert main(["simulate", "-o", str(project), "--strips", "2", "--photos", "4",
                 "--gnss", "0.05", "--gnss-offset", "0.2", "--imu", "0.005"]) == 0
    toml = project / "project.toml"
    toml.write_text(toml.read_text().replace('offsets = "strip"', f'offsets = "{offsets}"'))
    capsys.readouterr()
    for args in (["--bundle", "--replay", str(project), "-o", str(tmp_path / "out")],
                 ["--bundle", str(project)]):
        assert main(["online", *args]) == 2
        err = capsys.readouterr().err
        assert f'[gnss] offsets = "{offsets}"' in err and "baarda adjust" in err, err
        assert "Traceback" not in err
    assert not (tmp_path / "out" / "replay.csv").exists()
