"""`baarda review` as a process: the address on the first line, the token, SIGTERM ends it
and saves, a second review of the same OUT is refused."""

import json
import os
import signal
import subprocess
import sys
import urllib.error
import urllib.request
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.slow


def review(*args):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.Popen([sys.executable, "-m", "baarda", "review", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=ROOT, env=env)


def test_serve_edit_terminate_save(tmp_path):
    out = tmp_path / "out"
    p = review("examples/demo", "--no-browser", "-o", str(out))
    try:
        first = p.stdout.readline().strip()
        assert first.startswith("review: http://127.0.0.1:") and "/?token=" in first
        url = first.split(" ", 1)[1]
        base, token = url.split("/?token=")
        with pytest.raises(urllib.error.HTTPError) as e:
            urllib.request.urlopen(base + "/api/summary", timeout=30)
        assert e.value.code == 403
        req = urllib.request.Request(base + "/api/edits", data=json.dumps(
            {"action": "reject", "photo": "03008", "point": "007008", "component": "x"}
        ).encode(), headers={"X-Baarda-Token": token, "Content-Type": "application/json"})
        answer = json.load(urllib.request.urlopen(req, timeout=60))
        assert round(answer["summary"]["sigma0"], 4) == 1.3144
        second = review("examples/demo", "--no-browser", "-o", str(out))
        _, err = second.communicate(timeout=120)
        assert second.returncode == 4 and "another baarda review" in err
        p.send_signal(signal.SIGTERM)
        rest, err = p.communicate(timeout=120)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 143, err  # 128 + SIGTERM, the edits saved
    assert "1 edit(s) saved" in rest
    assert (out / "edits.csv").read_text().splitlines()[1].startswith(
        "reject,03008,007008,x,,,")
    assert (out / "observations.csv").is_file()
    assert not (tmp_path / ".out.review.lock").exists()


def test_ctrl_c_ends_with_130_and_keeps_the_edits(tmp_path):
    out = tmp_path / "out"
    p = review("examples/demo", "--no-browser", "-o", str(out))
    try:
        base, token = p.stdout.readline().strip().split(" ", 1)[1].split("/?token=")
        for body in ({"action": "reject", "photo": "03008", "point": "007008",
                      "component": "x"},
                     {"action": "reject", "photo": "03008", "point": "007008",
                      "component": "y"}):
            req = urllib.request.Request(base + "/api/edits", data=json.dumps(body).encode(),
                                         headers={"X-Baarda-Token": token,
                                                  "Content-Type": "application/json"})
            assert json.load(urllib.request.urlopen(req, timeout=60))["summary"]["edits"]
        p.send_signal(signal.SIGINT)
        rest, err = p.communicate(timeout=120)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 130, err
    assert "2 edit(s) saved" in rest and "Traceback" not in err
    rows = (out / "edits.csv").read_text().splitlines()[1:]
    assert [r.split(",")[:4] for r in rows] == [["reject", "03008", "007008", "x"],
                                               ["reject", "03008", "007008", "y"]]
    assert (out / "observations.csv").is_file()


def test_bad_port_is_bad_input():
    p = review("examples/demo", "--no-browser", "--port", "70000")
    _, err = p.communicate(timeout=120)
    assert p.returncode == 2 and "--port" in err
