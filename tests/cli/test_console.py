"""What a command tells its user (issue 29): -q keeps warnings and a one-line verdict, -qq
silences them; progress only on a terminal; a standard output or a disk that fails; a
terminal that cannot encode."""

import json
import os
import resource
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest
from cli.test_runs import leftovers, on_a_terminal

from baarda.cli import main
from baarda.io.run_manifest import MANIFEST

ROOT = Path(__file__).parents[2]
DEMO = ROOT / "examples" / "demo"


def baarda(*args: str, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "baarda", *args], cwd=ROOT, text=True,
                          timeout=300, **kwargs)


def test_quiet_adjust_of_the_demo_prints_the_verdict_line(tmp_path, capsys):
    assert main(["adjust", str(DEMO), "-o", str(tmp_path / "o"), "-q"]) == 0
    cap = capsys.readouterr()
    assert cap.out == ""
    assert cap.err == (f"baarda adjust: sigma0 1.463 (global test REJECTED), 0 rejected, 19 "
                       f"flagged, 4 check points RMS X 0.073 Y 0.042 Z 0.109 m; quality check "
                       f"FAIL: Global test -> {tmp_path / 'o'}\n")
    first = json.loads((tmp_path / "o" / MANIFEST).read_text())["run"]
    assert main(["adjust", str(DEMO), "-o", str(tmp_path / "o"), "-q", "--snoop"]) == 0
    assert capsys.readouterr().err == (
        "baarda adjust: sigma0 1.051 (global test accepted), 4 rejected, 4 check points RMS "
        "X 0.059 Y 0.046 Z 0.117 m; quality check REVIEW: Rejections, Suspicious GCPs -> "
        f"{tmp_path / 'o'} (replacing run {first})\n")
    assert main(["adjust", str(DEMO), "-o", str(tmp_path / "o"), "-qq"]) == 0
    assert capsys.readouterr() == ("", "")


def weak_control_project(tmp_path: Path) -> Path:
    """A block whose control lies on one edge only, with a systematic error in its heights
    (a 0.5 % scale error of Z): the check points far from the edge miss by metres."""
    from baarda.output.project_files import write_project
    from baarda.simulate.aerial import FlightPlan, simulate_block

    block, _ = simulate_block(FlightPlan(strips=4, photos_per_strip=8, check_points=6,
                                         relief_m=50.0, seed=2))
    pts = block.points
    edge = pts.xyz[:, 1] < pts.xyz[pts.role == "control", 1].min() + 1.0
    role = pts.role.copy()
    role[(pts.role == "control") & ~edge] = "tie"
    xyz, sigma = pts.xyz.copy(), pts.sigma.copy()
    xyz[role == "tie"] = float("nan")
    sigma[role != "control"] = float("nan")
    ctrl = role == "control"
    xyz[ctrl, 2] += 0.005 * (xyz[ctrl, 0] - xyz[ctrl, 0].mean())  # a tilt along the edge
    block = replace(block, points=replace(pts, role=role, xyz=xyz, sigma=sigma))
    write_project(block, tmp_path / "weak")
    return tmp_path / "weak"


def test_quiet_keeps_the_warning_and_the_verdict_of_a_weak_block(tmp_path, capsys):
    """The issue's case: check points that miss by metres under a weak-control warning
    printed nothing with -q."""
    proj = weak_control_project(tmp_path)
    assert main(["adjust", str(proj), "-o", str(tmp_path / "o"), "-q"]) == 0
    cap = capsys.readouterr()
    assert cap.out == ""
    lines = cap.err.splitlines()
    assert any(ln.startswith("note: weak control: the height control spans") for ln in lines)
    verdict = lines[-1]
    assert verdict.startswith("baarda adjust: sigma0 ") and "6 check points RMS X " in verdict
    rms = json.loads((tmp_path / "o" / "summary.json").read_text())["check_rms_Z"]
    assert rms > 1.0 and f"Z {rms:.3f} m" in verdict  # metres, said on the verdict line
    assert main(["adjust", str(proj), "-o", str(tmp_path / "o"), "-qq"]) == 0
    assert capsys.readouterr() == ("", "")


@pytest.mark.slow
def test_progress_only_on_a_terminal(tmp_path):
    p = baarda("adjust", str(DEMO), "-o", str(tmp_path / "a"), "--snoop",
               capture_output=True)
    assert p.returncode == 0
    assert p.stderr.splitlines() == [p.stderr.splitlines()[-1]]  # the verdict, no progress
    assert "iteration" not in p.stderr and "snooping 1" not in p.stderr
    proc, terminal = on_a_terminal(["adjust", str(DEMO), "-o", str(tmp_path / "b"),
                                    "--snoop"], cwd=ROOT)
    proc.wait(timeout=300)
    shown = terminal.rest()
    assert proc.returncode == 0
    assert "] read demo: 1 camera(s), 32 photos" in shown  # tqdm's status line: [mm:ss]
    assert "] snooping 4: sigma0 1.112, reject image photo 01004 point 002005 x" in shown
    proc, terminal = on_a_terminal(["adjust", str(DEMO), "-o", str(tmp_path / "c"), "-q"],
                                   cwd=ROOT)
    proc.wait(timeout=300)
    assert "iteration" not in terminal.rest()


@pytest.mark.slow
def test_evaluate_shows_a_bar_on_a_terminal(tmp_path):
    proc, terminal = on_a_terminal(["evaluate", "-o", str(tmp_path / "e"), "--trials", "3",
                                    "--strips", "2", "--photos", "3"], cwd=ROOT)
    proc.wait(timeout=300)
    shown = terminal.rest()
    assert proc.returncode == 0, shown
    assert "3/3 trials" in shown and "baarda evaluate: 3 trials of 4 strategies" in shown


def _closed_pipe() -> int:
    """The write end of a pipe whose read end is closed: every write fails with EPIPE (a
    reader gone, `baarda ... | head -c 0`), without a device node."""
    read, write = os.pipe()
    os.close(read)
    return write


@pytest.mark.slow
def test_a_failing_standard_output_follows_one_rule_for_every_command(tmp_path):
    """A closed pipe as stdout: a warning, the command goes on; where the results are files
    the exit code is the command's own (adjust 0), where the printout is the result it is 4
    (check, pattern, online --bundle --replay: check was 2 'Broken pipe', the replay 2)."""
    def run(*args: str) -> subprocess.CompletedProcess:
        write = _closed_pipe()
        try:
            return baarda(*args, stdout=write, stderr=subprocess.PIPE)
        finally:
            os.close(write)

    p = run("adjust", str(DEMO), "-o", str(tmp_path / "o"))
    assert p.returncode == 0, p.stderr
    assert "baarda: warning: could not print to standard output (Broken pipe); the " \
           "printout is lost, the files written are complete" in p.stderr
    assert "Traceback" not in p.stderr and "Exception ignored" not in p.stderr
    assert (tmp_path / "o" / "summary.json").is_file()
    for args in (("check", str(tmp_path / "o")), ("pattern", "9"),
                 ("online", "--bundle", "--replay", str(DEMO), "-o", str(tmp_path / "r"))):
        p = run(*args)
        assert p.returncode == 4, (args, p.stderr)
        assert "could not write the results to standard output (Broken pipe)" in p.stderr
        assert "Traceback" not in p.stderr and "Exception ignored" not in p.stderr
    assert (tmp_path / "r" / "summary.json").is_file()


def _limit_file_size():
    resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, 20_000))


@pytest.mark.slow
def test_a_full_disk_is_exit_4_naming_the_file_and_keeps_the_earlier_run(tmp_path):
    """ulimit -f: a file over the limit cannot be written (EFBIG): exit 4 (not 2, bad
    input), the file named at its place in the output folder, the earlier run intact."""
    out = tmp_path / "o"
    assert main(["adjust", str(DEMO), "-o", str(out), "-qq"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    p = baarda("adjust", str(DEMO), "-o", str(out), "-q", capture_output=True,
               preexec_fn=_limit_file_size)
    assert p.returncode == 4, p.stderr
    assert p.stderr == (f"baarda: error: could not write the results: "
                        f"{out / 'observations.csv'}: File too large\n")
    assert {q.name: q.read_bytes() for q in out.iterdir()} == before
    assert leftovers(tmp_path) == []


@pytest.mark.slow
def test_a_single_output_file_that_cannot_be_written_is_exit_4(tmp_path, capsys,
                                                                monkeypatch):
    out = tmp_path / "o"
    assert main(["adjust", str(DEMO), "-o", str(out), "-qq"]) == 0
    import errno

    from baarda.output import atomic

    def full(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(atomic.tempfile, "mkstemp", full)
    assert main(["report", str(out), "-o", str(tmp_path / "r" / "report.html")]) == 4
    assert capsys.readouterr().err.startswith(
        f"baarda: error: could not write the results: {tmp_path / 'r' / 'report.html'}: No "
        "space left on device")


@pytest.mark.slow
def test_a_terminal_that_cannot_encode_gets_escapes(tmp_path):
    """PYTHONIOENCODING=ascii: the summary's 'µm' ended in UnicodeEncodeError after the
    results were written."""
    p = baarda("adjust", str(DEMO), "-o", str(tmp_path / "o"), capture_output=True,
               env={**os.environ, "PYTHONIOENCODING": "ascii"})
    assert p.returncode == 0, p.stderr
    assert "a-priori sigmas: image 5 \\xb5m" in p.stdout
    assert "Traceback" not in p.stderr


@pytest.mark.parametrize("quiet", [[], ["-q"], ["-qq"]])
def test_errors_are_shown_however_quiet(tmp_path, capsys, quiet):
    assert main(["adjust", str(tmp_path / "missing"), "-o", str(tmp_path / "o"),
                 *quiet]) == 2
    assert capsys.readouterr().err.startswith("baarda: error: ")


@pytest.mark.parametrize("argv", [["simulate", "--strips", "2", "--photos", "3"],
                                  ["simulate-models", "--strips", "1", "--models", "2"]])
def test_simulate_commands_take_quiet(tmp_path, capsys, argv):
    """simulate and simulate-models had no -q (issue 43): without it they print a summary,
    with -q and -qq nothing on stdout."""
    assert main([*argv, "-o", str(tmp_path / "a")]) == 0
    assert capsys.readouterr().out != ""
    assert main([*argv, "-o", str(tmp_path / "b"), "-q"]) == 0
    assert capsys.readouterr().out == ""
    assert main([*argv, "-o", str(tmp_path / "c"), "-qq"]) == 0
    assert capsys.readouterr() == ("", "")
