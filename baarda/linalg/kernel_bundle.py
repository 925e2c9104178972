"""Compiled kernels shipped with the package: a first run that finds numba's cache empty takes
their machine code instead of compiling (about 15-30 s of CPU for the demo on 2 cores).

The bundle (:data:`BUNDLE_FILE`, xz-compressed pickle) holds, for every cached kernel, numba's
own cache entries: the index (argument types, the CPU's magic tuple, the hash of the kernel's
bytecode -> data file) and the data files.  :func:`seed` copies one kernel's entries into the
cache folder numba uses for it, with the index stamped for the installed source file, so that
numba loads them exactly as if it had compiled them here: the same machine code, the same
numbers.  The bundle is used only where it is that code: the same numba version, Python
version and CPU (numba's magic tuple: target, CPU name and features), and source files of
every kernel module equal, byte for byte, to the ones it was made from (a kernel inlines the
kernels it calls, from other modules too).  Anywhere else it is ignored and the kernels
compile as before (linalg/precompile.py).

``python -m baarda.cli.compile --bundle`` makes it (every kernel of the compile table
compiled in an empty cache), with the list of its kernels' names beside it (`names_file`).
``BAARDA_KERNEL_BUNDLE=0`` switches seeding off; ``BAARDA_KERNEL_BUNDLE=FILE`` seeds from
another bundle.
"""

from __future__ import annotations

import hashlib
import importlib.util
import lzma
import os
import pickle
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

__all__ = ["BUNDLE_FILE", "bundle_file", "bundle_key", "make_bundle", "seed"]

BUNDLE_FILE = Path(__file__).with_name("kernel_bundle.xz")
FORMAT = 1

_loaded: dict[Path, dict | None] = {}
_listed: dict[Path, frozenset[str] | None] = {}


def names_file(path: Path) -> Path:
    """The list of the kernels a bundle holds, one name per line, beside it (plain text:
    a kernel the bundle does not hold, such as one that only other kernels call and so never
    gets a cache index of its own, is told without decompressing the bundle, about 70 ms at
    every start)."""
    return path.with_name(path.name + ".names")


def _listed_names(path: Path) -> frozenset[str] | None:
    """The names in the bundle's list (read once per process); None without a list."""
    if path not in _listed:
        try:
            _listed[path] = frozenset(names_file(path).read_text("utf-8").split())
        except OSError:
            _listed[path] = None
    return _listed[path]


def _name(disp: Any) -> str:
    return f"{disp.py_func.__module__}.{disp.py_func.__qualname__}"


def _sources_hash(modules: Iterable[str]) -> str | None:
    """sha256 over the source files of `modules` (None when one cannot be found)."""
    h = hashlib.sha256()
    for module in sorted(modules):
        try:
            spec = importlib.util.find_spec(module)
        except (ImportError, ValueError):
            return None
        if spec is None or not spec.origin:
            return None
        try:
            h.update(module.encode() + b"\0" + Path(spec.origin).read_bytes() + b"\0")
        except OSError:
            return None
    return h.hexdigest()


def bundle_key() -> dict:
    """What must be equal for the bundle's code to be this installation's: numba's version,
    Python's and the CPU's magic tuple (numba's codegen)."""
    import numba
    from numba.core.registry import cpu_target

    return {"format": FORMAT, "numba": numba.__version__,
            "python": list(sys.version_info[:2]),
            "magic": cpu_target.target_context.codegen().magic_tuple()}


def make_bundle(dispatchers: Iterable[Any], path: Path = BUNDLE_FILE) -> int:
    """Write the bundle from numba's cache entries of `dispatchers` (those without any are
    left out); the number of kernels written."""
    entries: dict[str, dict] = {}
    modules: set[str] = set()
    for disp in dispatchers:
        cache = getattr(disp, "_cache", None)
        cf = getattr(cache, "_cache_file", None)
        if cf is None:
            continue
        overloads = cf._load_index()
        if not overloads:
            continue
        data = {name: Path(cf._data_path(name)).read_bytes() for name in overloads.values()}
        entries[_name(disp)] = {"overloads": overloads, "data": data}
        modules.add(disp.py_func.__module__)
    bundle = {**bundle_key(), "sources": _sources_hash(modules), "modules": sorted(modules),
              "kernels": entries}
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(lzma.compress(pickle.dumps(bundle, protocol=4), preset=6))
    listed = names_file(path)
    listed_tmp = listed.with_name(listed.name + ".tmp")
    listed_tmp.write_text("".join(f"{name}\n" for name in sorted(entries)), "utf-8")
    os.replace(tmp, path)
    os.replace(listed_tmp, listed)
    _loaded.pop(path, None)
    _listed.pop(path, None)
    return len(entries)


def _load(path: Path) -> dict | None:
    """The bundle at `path` if it is this installation's code (see the module), else None;
    read once per process."""
    if path in _loaded:
        return _loaded[path]
    bundle = None
    try:
        if path.is_file():
            data = pickle.loads(lzma.decompress(path.read_bytes()))
            key = bundle_key()
            if (all(data.get(k) == v for k, v in key.items())
                    and data.get("sources") == _sources_hash(data.get("modules", ()))):
                bundle = data
    except Exception:  # noqa: BLE001 - a damaged or foreign bundle: compile as before
        bundle = None
    _loaded[path] = bundle
    return bundle


def bundle_file() -> Path | None:
    """The bundle to seed from: the package's, another one (``BAARDA_KERNEL_BUNDLE=FILE``)
    or none (``BAARDA_KERNEL_BUNDLE=0``)."""
    choice = os.environ.get("BAARDA_KERNEL_BUNDLE", "")
    if choice == "0":
        return None
    return Path(choice) if choice else BUNDLE_FILE


def seed(disp: Any, path: Path | None = None) -> bool:
    """Put the bundle's code of the kernel `disp` into numba's cache where it has none
    (`path`: default :func:`bundle_file`); whether it did."""
    path = path or bundle_file()
    if path is None or not path.is_file():
        return False
    listed = _listed_names(path)
    if listed is not None and _name(disp) not in listed:
        return False
    bundle = _load(path)
    if bundle is None:
        return False
    entry = bundle["kernels"].get(_name(disp))
    if entry is None:
        return False
    try:
        cache = disp._cache
        cf = cache._cache_file
        cache._impl.locator.ensure_cache_path()
        for name, blob in entry["data"].items():
            with cf._open_for_write(cf._data_path(name)) as fh:
                fh.write(blob)
        cf._save_index(entry["overloads"])  # stamped for the installed source file
    except Exception:  # noqa: BLE001 - numba's internals changed, or no writable cache
        return False
    return True
