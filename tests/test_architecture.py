"""The layers of baarda import only downward (docs/architecture.md), checked on the source.

Every `import baarda.x` / `from baarda.x import ...` in a module of package P (including the
ones inside functions and under TYPE_CHECKING) must name a package of a lower floor than P,
or P itself.  Floors, from the ground up: see FLOORS.
"""

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "baarda"

FLOORS = [
    {"kinds"},
    {"errors", "options", "schema", "sections", "table_data", "linalg", "process"},
    {"block"},
    {"io", "quality"},
    {"adjustment"},
    {"bundle", "relative"},
    {"screening", "independent", "gcp_placement"},
    {"pipeline", "simulate"},
    {"planning", "online"},
    {"evaluation"},
    {"output"},
    {"report"},
    {"review"},
    {"cli"},
    {"__init__", "__main__"},
]
FLOOR = {pkg: i for i, floor in enumerate(FLOORS) for pkg in floor}
READERS_MAY_NOT_IMPORT = {"bundle", "independent", "relative", "screening", "adjustment",
                          "quality", "output", "report", "pipeline", "planning", "simulate",
                          "cli"}


def package_of(path: Path) -> str:
    rel = path.relative_to(ROOT)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def absolute(path: Path, level: int, module: str | None) -> str:
    """The absolute name of a relative import (`from ..x import y` in `path`): path is a
    module of baarda/ or a file taken for one (the test of the rule)."""
    try:
        parts = ["baarda", *path.relative_to(ROOT).parts[:-1]]
    except ValueError:  # a file outside the package: taken for a module of baarda/io
        parts = ["baarda", "io"]
    base = parts[:len(parts) - (level - 1)] if level > 1 else parts
    return ".".join(base + ([module] if module else []))


def baarda_imports(path: Path) -> list[tuple[int, str]]:
    """(line, package) of every import of a baarda package in the file, relative imports
    (`from .kernels import`, `from ..bundle import`) included."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and (node.module or node.level):
            module = (absolute(path, node.level, node.module) if node.level
                      else node.module)
            names = [module]
            if module == "baarda":
                names = [f"baarda.{a.name}" for a in node.names]
        for name in names:
            parts = name.split(".")
            if parts[0] == "baarda" and len(parts) > 1:
                out.append((node.lineno, parts[1]))
    return out


MODULES = sorted(ROOT.rglob("*.py"))


def test_every_package_has_a_floor():
    pkgs = {package_of(p) for p in MODULES}
    assert pkgs <= set(FLOOR), f"packages without a floor: {sorted(pkgs - set(FLOOR))}"


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_only_downward(path):
    own = package_of(path)
    bad = [f"line {line}: {own} (floor {FLOOR[own]}) imports {pkg} (floor {FLOOR[pkg]})"
           for line, pkg in baarda_imports(path) if pkg != own and FLOOR[pkg] >= FLOOR[own]]
    assert not bad, "\n".join(bad)


def test_readers_import_no_computation():
    bad = [f"{p.relative_to(ROOT)} line {line}: imports baarda.{pkg}"
           for p in sorted((ROOT / "io").rglob("*.py"))
           for line, pkg in baarda_imports(p) if pkg in READERS_MAY_NOT_IMPORT]
    assert not bad, "\n".join(bad)


# The words of docs/architecture.md as rules (issue 27): package -> what it never imports.
METHODS = {"bundle", "independent", "relative", "screening"}
NEVER = {
    # the methods compute: they neither read files nor write them nor orchestrate
    **{m: {"io", "output", "report", "pipeline"} for m in METHODS},
    # the command line only parses: it calls the pipeline (or a method's entry point on a
    # higher floor: planning, evaluation) and the writers
    "cli": METHODS | {"adjustment", "quality"},
    # the writers write what they are given
    "output": {"pipeline", "adjustment", "relative"},
}


@pytest.mark.parametrize("package", sorted(NEVER))
def test_what_a_package_never_imports(package):
    bad = [f"{p.relative_to(ROOT)} line {line}: imports baarda.{pkg}"
           for p in sorted((ROOT / package).rglob("*.py"))
           for line, pkg in baarda_imports(p) if pkg in NEVER[package]]
    assert not bad, "\n".join(bad)


REPORT_MAY_NOT_IMPORT = {"pipeline", "bundle", "independent", "relative", "screening",
                         "adjustment", "quality", "evaluation", "planning", "simulate"}


def test_the_report_reads_result_files_only():
    """report/ renders what the result files say (issue 27): it never imports the
    pipeline, the methods, the solver, the quality layer, the studies or the planning."""
    bad = [f"{p.relative_to(ROOT)} line {line}: imports baarda.{pkg}"
           for p in sorted((ROOT / "report").rglob("*.py"))
           for line, pkg in baarda_imports(p) if pkg in REPORT_MAY_NOT_IMPORT]
    assert not bad, "\n".join(bad)


def test_readers_live_in_io():
    """Residual listings of other programs and a result folder are read by io/
    (residual_listings.py, result_folder.py, observations_file.py, run_manifest.py), not by
    the report or the writers (issue 27)."""
    for name in ("residual_listings", "result_folder", "observations_file", "run_manifest"):
        assert (ROOT / "io" / f"{name}.py").is_file(), name
    assert not (ROOT / "report" / "residual_readers.py").exists()
    assert not (ROOT / "output" / "result_folder.py").exists()


def test_the_rule_catches_an_upward_import(tmp_path):
    """The check itself: an io module that imports the bundle is found."""
    f = tmp_path / "bad.py"
    f.write_text("def f():\n    from baarda.bundle.bundle_problem import BundleProblem\n")
    assert baarda_imports(f) == [(2, "bundle")]
    assert FLOOR["bundle"] > FLOOR["io"]


def test_the_rule_follows_relative_imports(tmp_path):
    """A relative import is resolved against its module: `from ..bundle import x` in io/ is
    the bundle, `from .kernels import` in linalg/ is linalg itself."""
    f = tmp_path / "bad.py"
    f.write_text("from ..bundle.bundle_problem import BundleProblem\nfrom . import table\n")
    assert baarda_imports(f) == [(1, "bundle"), (2, "io")]
    assert (19, "linalg") in baarda_imports(ROOT / "linalg" / "blocksparse.py")
    assert all(pkg == "linalg" for _, pkg in baarda_imports(ROOT / "linalg" / "kernels.py"))


LOOP_SIGNS = re.compile(r"\b(step|t)\s*\*=\s*0\.5|for _ in range\(iterations\)|"
                        r"while step >")


NOT_ADJUSTMENTS = {
    "adjustment/solve.py": "the solver",
    "block/camera.py": "the inverse of the lens model by Newton's method (one equation per "
                       "point, not a least-squares adjustment)",
    "block/camera_models.py": "the inverse of a camera model by Newton's method (one 2x2 "
                              "system per point, not a least-squares adjustment)",
}


def test_one_iteration_loop():
    """Gauss-Newton with step halving lives in adjustment/solve.py only; every adjustment
    calls solve() (the signs of a loop of its own: halving a step, iterating a count)."""
    found = [f"{p.relative_to(ROOT)}: {m.group(0)}" for p in MODULES
             if p.relative_to(ROOT).as_posix() not in NOT_ADJUSTMENTS
             and package_of(p) != "linalg"
             for m in LOOP_SIGNS.finditer(p.read_text(encoding="utf-8"))]
    assert not found, found
    assert LOOP_SIGNS.search((ROOT / "adjustment" / "solve.py").read_text())


def test_the_package_table_lists_every_module():
    """docs/architecture.md's table of packages names every module in its package's row
    (a top-level module has a row of its own)."""
    doc = (ROOT.parent / "docs" / "architecture.md").read_text(encoding="utf-8")
    rows = {m.group(1).rstrip("/"): m.group(2)
            for m in re.finditer(r"^\| `([^`]+)` \|(.*)\|$", doc, re.MULTILINE)}
    missing = []
    for p in MODULES:
        rel = p.relative_to(ROOT)
        if p.name in ("__init__.py", "__main__.py"):
            continue
        if len(rel.parts) == 1:
            ok = p.name in rows or p.stem in rows
        else:
            ok = f"`{p.name}`" in rows.get(rel.parts[0], "")
        if not ok:
            missing.append(rel.as_posix())
    assert not missing, missing
