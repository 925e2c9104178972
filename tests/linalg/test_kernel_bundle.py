"""The package's compiled kernels (linalg/kernel_bundle.py): a first run with an empty cache
loads them instead of compiling, where they are this installation's code, and only there."""

import json
import lzma
import os
import pickle
import subprocess
import sys

import numpy as np
import pytest

from baarda.linalg import kernel_bundle
from baarda.linalg.symbolic import elimination_tree

MAKE = """
import sys
from pathlib import Path
import numpy as np
from baarda.linalg.kernel_bundle import make_bundle
from baarda.linalg.symbolic import elimination_tree, etree_postorder
etree_postorder(elimination_tree(3, np.array([0, 0, 1, 2]), np.array([0, 1])))
print(make_bundle([elimination_tree, etree_postorder], Path(sys.argv[1])))
"""

USE = """
import json
import numpy as np
from baarda.linalg import precompile
from baarda.linalg.symbolic import elimination_tree, etree_postorder
print(json.dumps([e["name"] for e in precompile.pending_kernels()]))
parent = elimination_tree(3, np.array([0, 0, 1, 2]), np.array([0, 1]))
post = etree_postorder(parent)
print(json.dumps([sum(k.stats.cache_hits.values()) for k in (elimination_tree, etree_postorder)]
                 + [sum(k.stats.cache_misses.values())
                    for k in (elimination_tree, etree_postorder)]))
print(json.dumps([parent.tolist(), post.tolist()]))
"""


def _python(code, env, *args):
    return subprocess.run([sys.executable, "-c", code, *args], env=env, capture_output=True,
                          text=True, check=True).stdout.strip().splitlines()


@pytest.mark.slow
def test_a_first_run_loads_the_bundled_kernels_instead_of_compiling(tmp_path):
    bundle = tmp_path / "bundle.xz"
    made = _python(MAKE, {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "a"),
                          "BAARDA_KERNEL_BUNDLE": "0"}, str(bundle))
    assert made[-1] == "2"
    fresh = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "b"),
             "BAARDA_KERNEL_BUNDLE": str(bundle)}
    pending, stats, numbers = _python(USE, fresh)
    assert "elimination_tree" not in json.loads(pending)  # in the cache before any call
    assert "supernodal_cholesky" in json.loads(pending)  # not in this bundle: compiled
    assert json.loads(stats) == [1, 1, 0, 0]  # loaded from the cache, nothing compiled
    # the same numbers as the compiled kernels (an independent process, no bundle)
    off = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "c"), "BAARDA_KERNEL_BUNDLE": "0"}
    pending_off, stats_off, numbers_off = _python(USE, off)
    assert "elimination_tree" in json.loads(pending_off)
    assert json.loads(stats_off)[2:] == [1, 1]  # compiled there
    assert numbers == numbers_off
    assert json.loads(numbers) == [[1, 2, -1], [0, 1, 2]]  # a chain: 0 -> 1 -> 2
    # a cache of an older source (its index stamped for another file): the bundle replaces it
    for index in (tmp_path / "c").rglob("symbolic.*.nbi"):
        with open(index, "rb") as fh:
            version = pickle.load(fh)
            stamp, overloads = pickle.loads(fh.read())
        with open(index, "wb") as fh:
            pickle.dump(version, fh)
            fh.write(pickle.dumps(((0.0, 0), overloads)))
    stale = {**off, "BAARDA_KERNEL_BUNDLE": str(bundle)}
    _, stats_stale, numbers_stale = _python(USE, stale)
    assert json.loads(stats_stale) == [1, 1, 0, 0] and numbers_stale == numbers


def _rewrite(path, target, **changes):
    data = pickle.loads(lzma.decompress(path.read_bytes()))
    data.update(changes)
    target.write_bytes(lzma.compress(pickle.dumps(data)))
    return target


def test_a_bundle_of_other_code_is_ignored(tmp_path):
    elimination_tree(3, np.array([0, 0, 1, 2]), np.array([0, 1]))  # compiled or cached here
    good = tmp_path / "good.xz"
    assert kernel_bundle.make_bundle([elimination_tree], good) == 1
    assert kernel_bundle._load(good) is not None
    assert "baarda.linalg.symbolic.elimination_tree" in kernel_bundle._load(good)["kernels"]
    for name, change in [("numba", {"numba": "0.0.1"}), ("python", {"python": [2, 7]}),
                         ("cpu", {"magic": ("x86_64-unknown-linux-gnu", "i386", "")}),
                         ("sources", {"sources": "0" * 64}),
                         ("module", {"modules": ["baarda.no_such_module"]})]:
        foreign = _rewrite(good, tmp_path / f"{name}.xz", **change)
        assert kernel_bundle._load(foreign) is None, name
        assert not kernel_bundle.seed(elimination_tree, foreign), name
    damaged = tmp_path / "damaged.xz"
    damaged.write_bytes(good.read_bytes()[:100])
    assert kernel_bundle._load(damaged) is None


def test_the_bundle_can_be_switched_off_or_replaced(monkeypatch, tmp_path):
    monkeypatch.setenv("BAARDA_KERNEL_BUNDLE", "0")
    assert kernel_bundle.bundle_file() is None
    monkeypatch.setenv("BAARDA_KERNEL_BUNDLE", str(tmp_path / "b.xz"))
    assert kernel_bundle.bundle_file() == tmp_path / "b.xz"
    assert not kernel_bundle.seed(elimination_tree)  # no such file
    monkeypatch.delenv("BAARDA_KERNEL_BUNDLE")
    assert kernel_bundle.bundle_file() == kernel_bundle.BUNDLE_FILE


def test_a_kernel_the_bundle_does_not_hold_is_told_from_its_list(tmp_path, monkeypatch):
    """Kernels that only other kernels call never get a cache index of their own, so every
    start asked the bundle for them and decompressed it (about 70 ms); the list of names
    beside the bundle answers without decompressing."""
    from baarda.linalg.symbolic import etree_postorder

    elimination_tree(3, np.array([0, 0, 1, 2]), np.array([0, 1]))  # compiled or cached here
    good = tmp_path / "good.xz"
    assert kernel_bundle.make_bundle([elimination_tree], good) == 1
    listed = kernel_bundle.names_file(good)
    assert listed.read_text() == "baarda.linalg.symbolic.elimination_tree\n"
    loads = []
    monkeypatch.setattr(kernel_bundle, "_load", lambda path: loads.append(path))
    assert not kernel_bundle.seed(etree_postorder, good)  # not listed: the bundle unread
    assert loads == []
    kernel_bundle.seed(elimination_tree, good)  # listed: the bundle is read
    assert loads == [good]
    # the package's list names every kernel its bundle holds
    shipped = pickle.loads(lzma.decompress(kernel_bundle.BUNDLE_FILE.read_bytes()))
    assert sorted(shipped["kernels"]) == \
        kernel_bundle.names_file(kernel_bundle.BUNDLE_FILE).read_text().split()
