"""Compiling the kernels in parallel processes before the first run (linalg/precompile.py)."""

import json
import os
import subprocess
import sys

import pytest
from numba.core import types

from baarda.cli import main as cli_main
from baarda.linalg import precompile


def test_argument_types_as_text_round_trip():
    sig = (types.Array(types.float64, 3, "C"), types.Array(types.int64, 1, "C"),
           types.Array(types.float64, 2, "C", readonly=True), types.Array(types.bool_, 1, "A"),
           types.int64, types.float64, types.boolean)
    spec = precompile.signature_spec(sig)
    assert spec == ["float64[3C]", "int64[1C]", "float64[2Cr]", "bool[1A]", "int64", "float64",
                    "bool"]
    assert precompile.spec_signature(spec) == sig
    with pytest.raises(ValueError, match="no text form"):
        precompile.signature_spec((types.UniTuple(types.int64, 2),))


def test_table_names_caching_kernels_and_the_core():
    table = precompile.load_table()
    names = {e["name"] for e in table}
    # the kernels every adjustment runs
    assert {"assemble", "reduce_points", "reduce_points_parallel", "elimination_tree",
            "supernodal_cholesky"} <= names
    for entry in table:
        disp = precompile._dispatcher(entry)
        assert disp._cache is not None, entry["name"]
        assert entry["seconds"] > 0 and entry["signatures"]


WORKLOAD = """
import json
from baarda.cli.compile import record_workload
from baarda.linalg import precompile
record_workload()
print(json.dumps({e["name"]: [precompile.signature_spec(s)
                  for s in precompile._dispatcher(e).signatures]
                  for e in precompile.load_table()}))
"""


@pytest.mark.slow
def test_table_has_the_argument_types_an_adjustment_compiles():
    # in a child: the workload starts numba's threads, after which pytest could not fork
    out = subprocess.run([sys.executable, "-c", WORKLOAD], capture_output=True, text=True,
                         check=True, env={**os.environ, "NUMBA_NUM_THREADS": "2"}).stdout
    used = json.loads(out.strip().splitlines()[-1])
    for entry in precompile.load_table():
        assert used[entry["name"]] == entry["signatures"], (
            f"{entry['module']}.{entry['name']}: the table's argument types are not the ones "
            "an adjustment uses; run `python -m baarda.cli.compile --record` with an "
            "empty NUMBA_CACHE_DIR")


CHECK = """
import json, sys
import numpy as np
from baarda.linalg import precompile
from baarda.linalg.symbolic import elimination_tree, etree_postorder
print(json.dumps([e["name"] for e in precompile.pending_kernels()]))
parent = elimination_tree(3, np.array([0, 0, 1, 2]), np.array([0, 1]))
etree_postorder(parent)
print(json.dumps([sum(k.stats.cache_hits.values()) for k in (elimination_tree, etree_postorder)]))
"""


@pytest.mark.slow
def test_kernels_compiled_by_child_processes_are_loaded_from_the_cache(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path), "BAARDA_KERNEL_BUNDLE": "0"}
    entries = [e for e in precompile.load_table()
               if e["name"] in ("elimination_tree", "etree_postorder")]
    assert len(entries) == 2
    code = ("import json, sys; from baarda.linalg import precompile; "
            "print(json.dumps(precompile.compile_kernels(jobs=2, "
            "entries=json.loads(sys.argv[1]))))")
    out = subprocess.run([sys.executable, "-c", code, json.dumps(entries)], env=env,
                         capture_output=True, text=True, check=True).stdout
    assert json.loads(out) == []  # nothing failed
    lines = subprocess.run([sys.executable, "-c", CHECK], env=env, capture_output=True,
                           text=True, check=True).stdout.strip().splitlines()
    pending = json.loads(lines[0])
    assert "elimination_tree" not in pending and "etree_postorder" not in pending
    assert "supernodal_cholesky" in pending  # the rest was not compiled
    assert json.loads(lines[1]) == [1, 1]  # loaded from the cache, not compiled


def test_a_kernel_that_cannot_be_compiled_is_named(monkeypatch):
    bad = {"module": "baarda.linalg.symbolic", "name": "no_such_kernel", "parallel": False,
           "seconds": 1.0, "signatures": [["int64"]]}
    assert precompile.compile_kernels(jobs=1, entries=[bad]) == [
        "baarda.linalg.symbolic.no_such_kernel"]


def test_compile_command(monkeypatch, capsys):
    monkeypatch.setattr(precompile, "pending_kernels", lambda parallel=True: [])
    assert cli_main(["compile"]) == 0
    assert "every kernel is compiled already" in capsys.readouterr().out
    bad = {"module": "baarda.nowhere", "name": "k", "parallel": False, "seconds": 1.0,
           "signatures": [["int64"]]}
    monkeypatch.setattr(precompile, "pending_kernels", lambda parallel=True: [bad])
    assert cli_main(["compile", "-j", "1"]) == 1
    assert "could not compile 1 kernel(s): baarda.nowhere.k" in capsys.readouterr().out
