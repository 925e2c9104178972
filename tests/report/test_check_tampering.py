"""`baarda check` that can fail (issue 43): the top-level figures of summary.json, the files
run.json lists, the columns the checks need and the relations of every row's statistics to
its residual and sigma (w = -v / sigma_residual, sigma_residual = sigma sqrt(r), MDB =
delta0 sigma / sqrt(r)).  Each tampering below, with run.json re-signed where the file is
listed, passed as "N of N invariants hold" before; now it is exit 5, "DOES NOT HOLD"."""

import json
import shutil
from pathlib import Path

import pytest

from baarda.cli import main
from baarda.io.run_manifest import file_record

DEMO = Path(__file__).resolve().parents[2] / "examples" / "demo"


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    out = tmp_path_factory.mktemp("res") / "out"
    assert main(["adjust", str(DEMO), "-o", str(out), "-q"]) == 0
    return out


def resign(folder: Path, name: str) -> None:
    m = json.loads((folder / "run.json").read_text())
    m["files"][name] = file_record(folder / name)
    (folder / "run.json").write_text(json.dumps(m))


def edit_summary(change):
    def do(folder: Path) -> None:
        d = json.loads((folder / "summary.json").read_text())
        change(d)
        (folder / "summary.json").write_text(json.dumps(d))
        resign(folder, "summary.json")
    return do


def edit_cell(column: str, value, row_kind: str = "image", drop: bool = False):
    """Set `column` of the first used image row with a w-test (or drop the column)."""
    def do(folder: Path) -> None:
        p = folder / "observations.csv"
        lines = p.read_text().splitlines()
        head = lines[0].split(",")
        k = head.index(column)
        if drop:
            lines = [",".join(f for i, f in enumerate(s.split(",")) if i != k) for s in lines]
        else:
            iw, ikind, irej = head.index("w"), head.index("kind"), head.index("rejected")
            n = next(i for i, s in enumerate(lines[1:], 1) if s.split(",")[iw] and
                     s.split(",")[ikind] == row_kind and s.split(",")[irej] == "False")
            f = lines[n].split(",")
            f[k] = value(f[k]) if callable(value) else value
            lines[n] = ",".join(f)
        p.write_text("\n".join(lines) + "\n")
        resign(folder, "observations.csv")
    return do


def delete(name: str):
    return lambda folder: (folder / name).unlink()


def change_unsigned(folder: Path) -> None:
    p = folder / "points.csv"
    p.write_text(p.read_text().replace(",control,", ",check,", 1))


CASES = {
    "top_sigma0": (edit_summary(lambda d: d.update(sigma0=1.5)),
                   "summary.json (top level): sigma0"),
    "top_redundancy": (edit_summary(lambda d: d.update(redundancy=999)),
                       "summary.json (top level): redundancy"),
    "top_observations": (edit_summary(lambda d: d.update(n_observations=1)),
                         "summary.json (top level): observations"),
    "top_global_test": (edit_summary(lambda d: d["global_test"].update(statistic=2.25)),
                        "summary.json (top level): global test statistic"),
    "points_deleted": (delete("points.csv"), "points.csv (listed in run.json): missing"),
    "photos_deleted": (delete("photos.csv"), "photos.csv (listed in run.json): missing"),
    "changed_unsigned": (change_unsigned, "points.csv (listed in run.json): size or SHA-256 "
                         "differ"),
    "redundancy_dropped": (edit_cell("redundancy", None, drop=True),
                           "every used row has residual, sigma, redundancy"),
    "w_edited": (edit_cell("w", lambda s: repr(float(s) + 0.5)), "w = -v / sigma_residual"),
    "mdb_edited": (edit_cell("mdb", lambda s: repr(float(s) * 0.5)), "MDB = delta0 sigma"),
    "sigma_negative": (edit_cell("sigma", "-5"), "sigma > 0 and 0 <= r <= 1"),
    "kind_changed": (edit_cell("kind", "gnss"), "kind and component is one of"),
    "component_changed": (edit_cell("component", "Z"), "kind and component is one of"),
    "sigma_residual_edited": (edit_cell("sigma_residual", lambda s: repr(float(s) * 1.1)),
                              "sigma_residual = sigma sqrt(r)"),
}


def test_an_untouched_folder_holds(results, capsys):
    assert main(["check", str(results)]) == 0
    out = capsys.readouterr().out
    assert "DOES NOT HOLD" not in out
    for name in ("summary.json (top level): sigma0", "w = -v / sigma_residual in every used "
                 "row: all 598 rows", "points.csv (listed in run.json): size and SHA-256 as "
                 "listed", "MDB = delta0 sigma / sqrt(r)"):
        assert name in out


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_tampered_folder_does_not_hold(results, tmp_path, capsys, case):
    folder = tmp_path / "out"
    shutil.copytree(results, folder)
    tamper, said = CASES[case]
    tamper(folder)
    code = main(["check", str(folder)])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    assert code == 5, out + err
    bad = [s for s in out.splitlines() if "DOES NOT HOLD" in s]
    assert any(said in s for s in bad), bad
