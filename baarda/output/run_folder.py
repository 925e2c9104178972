"""One run, one folder: results are written into a staging folder beside the output folder
and moved into place when the run is complete, so a folder holds one whole run or the
previous one, never a mix.

    with RunFolder(out, inputs=[project]) as run:   # checks the place before computing
        ...compute...
        write_results(run, qc)                      # writes into run.path (the staging)
    # on leaving: run.json (the manifest) is written and the folder moved into place;
    # on an error or Ctrl-C the staging folder is removed and `out` is untouched

A run killed outright (SIGKILL, a power cut) cannot remove its staging folder: the next run
into the same place removes what such runs left (`.OUT.<run>.partial`, and `.OUT.<run>.old`,
an earlier run moved aside while a run was committing; when the output folder itself is
missing, that earlier run is moved back) and says so in `cleaned`.  A folder still in use by
a live run is told apart by its lock (flock on the staging folder, released by the kernel when
the process dies).

run.json names the run (id, time, baarda version) and every file with its size and SHA-256,
so that `baarda report` can refuse a folder whose files do not belong to one run
(`verify_run`).  An output folder may be new, empty, or a folder that baarda wrote (it has
run.json or summary.json); anything else is refused before any work is done, and so is a
place that would cover an input.  A new run replaces only the files of the earlier run
(those its run.json lists): any other file in the folder (a report written into it, a file
of the user's) is kept where it is, and said (`kept`).  Two runs into the same folder at
once: the later one is refused while the first holds the lock of its staging folder.
"""

from __future__ import annotations

import errno
import json
import os
import re
import secrets
import shutil
import sys
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path

from baarda.errors import OutputError, ProjectError
from baarda.io.run_manifest import MANIFEST, file_record

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: leftovers are left, never taken away
    fcntl = None  # type: ignore[assignment]

MARKERS = (MANIFEST, "summary.json")  # a folder with one of them was written by baarda


def new_run_id() -> str:
    """A run id: UTC time and 24 random bits (e.g. 20261123T101502Z-3fa9c1)."""
    return f"{datetime.now(UTC):%Y%m%dT%H%M%SZ}-{secrets.token_hex(3)}"


def package_version() -> str:
    """The installed version of baarda."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("baarda")
    except PackageNotFoundError:  # pragma: no cover - a source tree without installation
        return "unknown"


def resolved(path: str | Path) -> Path:
    """`path` made absolute with its links followed; a ProjectError naming it for a link
    loop or a name the system refuses (too long)."""
    path = Path(path)
    try:
        return path.expanduser().resolve()
    except RuntimeError:  # pathlib's "Symlink loop"
        raise ProjectError(str(path), "is a symbolic link loop; give another name") from None
    except OSError as e:
        raise ProjectError(str(path), f"cannot be used ({e.strerror})") from None


#: why an output place cannot be written that is no fault of its name (exit 4, like a write
#: that fails later: the tutorial's "disk full, no permission"): a path of the wrong kind
#: (a file where a folder is named, /proc) is bad input (exit 2)
UNWRITABLE = {errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOSPC, errno.EDQUOT}


def place_error(path: Path, e: OSError, said: str) -> Exception:
    """The error of an output place at `path` that cannot be used: OutputError (exit 4) for
    a permission, a read-only file system or a full disk, else ProjectError (`said` and
    the system's reason)."""
    if e.errno in UNWRITABLE:
        return OutputError(e.errno, f"{e.strerror}; choose another place with -o", str(path))
    return ProjectError(str(path), f"{said} ({e.strerror}); choose another place with -o")


def _covers(out: Path, path: Path) -> bool:
    return out == path or out in path.parents


def check_output_folder(out: str | Path, inputs: Iterable[str | Path] = ()) -> Path:
    """The resolved output folder, or a ProjectError saying why it cannot be one: an
    existing file, an input or a folder holding an input, a folder that baarda did not
    write (a run replaces an earlier run's files only: its run.json tells them)."""
    out = resolved(out)
    for p in (resolved(q) for q in inputs if q is not None):
        if _covers(out, p):
            what = "is" if out == p else "holds"
            raise ProjectError(str(out), f"the output folder {what} the input {p}; choose "
                               "another with -o (inputs are never overwritten)")
    if out.exists() and not out.is_dir():
        raise ProjectError(str(out), "exists and is not a folder; give a folder name with -o")
    if out.is_dir():
        try:
            entries = sorted(e.name for e in out.iterdir())
        except OSError as e:
            raise place_error(out, e, "cannot be read") from None
        if entries and not any(m in entries for m in MARKERS):
            shown = ", ".join(entries[:5]) + (", ..." if len(entries) > 5 else "")
            raise ProjectError(str(out), f"exists and holds files that baarda did not write "
                               f"({shown}); a run goes into a new or empty folder or one that "
                               "baarda wrote (it replaces that run's files): choose another "
                               "with -o")
    return out


def check_output_file(out: str | Path, inputs: Iterable[str | Path] = ()) -> Path:
    """The resolved path of a single output file (a report, a drawing), checked before any
    work: not a folder, not one of the inputs, its folder writable (or creatable: missing
    folders are made when the file is written, so a failed run leaves none)."""
    from baarda.output.atomic import output_target

    out = resolved(output_target(Path(out).expanduser()))
    for p in (resolved(q) for q in inputs if q is not None):
        if out == p:
            raise ProjectError(str(out), "is an input (inputs are never overwritten); choose "
                               "another file with -o")
    if out.is_dir():
        raise ProjectError(str(out), "is a folder; give a file name with -o")
    parent = out.parent  # created when the file is written, not before: the nearest folder
    while not parent.exists() and parent != parent.parent:  # that exists must allow it
        parent = parent.parent
    if not parent.is_dir():
        raise ProjectError(str(parent), "is not a folder; choose another place with -o")
    try:  # a file that is gone when closed: whether this place takes files (/proc does not)
        with tempfile.TemporaryFile(dir=parent):
            pass
    except OSError as e:
        raise place_error(parent, e, "cannot write a file here") from None
    return out


def run_files(folder: str | Path) -> list[Path]:
    """The files of a result folder that a run wrote (those run.json lists, else every
    .csv, .json and .txt file)."""
    folder = Path(folder)
    listed = _listed(folder)
    if listed is not None:
        return [folder / name for name in sorted(listed)]
    return [p for p in folder.glob("*") if p.suffix in (".csv", ".json", ".txt")]


def _listed(folder: Path) -> set[str] | None:
    """The files the run.json of `folder` lists (with run.json itself), None without a
    readable run.json."""
    try:
        files = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))["files"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not isinstance(files, dict):
        return None
    return {MANIFEST, *files}


def foreign_files(folder: str | Path) -> list[str]:
    """The files (and links) of a result folder that no run of baarda wrote there: those its
    run.json does not list; for a folder written before run.json existed, all but its .csv,
    .json and .txt files.  Paths relative to the folder, sorted."""
    folder = Path(folder)
    listed = _listed(folder)
    found = []
    for root, dirs, names in os.walk(folder):
        here = Path(root)
        for name in [*names, *(d for d in dirs if (here / d).is_symlink())]:
            rel = (here / name).relative_to(folder).as_posix()
            if listed is not None:
                if rel not in listed:
                    found.append(rel)
            elif "/" in rel or Path(rel).suffix not in (".csv", ".json", ".txt"):
                found.append(rel)
    return sorted(found)


def _carry(src: Path, dst: Path) -> None:
    """Put the file (or link) `src` at `dst` too: a hard link (the file stays where it was
    until the folder is swapped, so a killed run loses nothing), else a copy."""
    dst.parent.mkdir(parents=True, exist_ok=True)
    if src.is_symlink():
        os.symlink(os.readlink(src), dst)
        return
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)


_LEFTOVER = re.compile(r"\.(?P<name>.+)\.(?P<run>\d{8}T\d{6}Z-[0-9a-f]{6})\."
                       r"(?P<kind>partial|old)")


def _lock(path: Path) -> int | None:
    """An exclusive lock on the folder `path` (its file descriptor), None when another
    process holds one (or the folder is gone)."""
    if fcntl is None:  # pragma: no cover
        return None
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    return fd


def _unlock(fd: int | None) -> None:
    if fd is not None:
        os.close(fd)  # closing releases the lock


def remove_leftovers(final: Path) -> list[str]:
    """Remove what runs into `final` that were killed left beside it (module docstring); a
    sentence for each.  When `final` is missing and an earlier run was moved aside
    (.old), the newest such run is moved back first."""
    said: list[str] = []
    try:
        found = sorted((m.group("run"), m.group("kind"), p) for p in final.parent.iterdir()
                       if (m := _LEFTOVER.fullmatch(p.name)) and m.group("name") == final.name
                       and p.is_dir() and not p.is_symlink())
    except OSError:
        return said
    olds = [p for _, kind, p in found if kind == "old"]
    if olds and not final.exists():
        fd = _lock(olds[-1])
        if fd is not None:
            try:
                os.replace(olds[-1], final)
                said.append(f"moved {olds[-1].name} back to {final}: a killed run had moved "
                            f"{earlier_run(final) or 'the earlier run'} aside")
            except OSError:
                pass
            finally:
                _unlock(fd)
    for _, kind, p in found:
        if not p.exists():
            continue
        fd = _lock(p)
        if fd is None:  # in use by a live run
            continue
        try:
            shutil.rmtree(p, ignore_errors=True)
        finally:
            _unlock(fd)
        what = "staging folder" if kind == "partial" else "earlier run"
        if p.exists():
            said.append(f"could not remove {p} (the {what} of a killed run); remove it by "
                        "hand")
        else:
            said.append(f"removed {p.name}, the {what} that a killed run left beside "
                        f"{final.name}")
    return said


class RunFolder:
    """The staging folder of one run (module docstring).  `path` is where to write, `final`
    the output folder, `run_id` the id every file of the run is listed under; `cleaned`
    says what killed runs had left and this one removed, `warnings` what went wrong after
    the results were in place (an earlier run that could not be removed)."""

    def __init__(self, out: str | Path, inputs: Iterable[str | Path] = (),
                 command: str | None = None, excel_safe: bool = False):
        self.given = Path(out)
        # the tables' text cells that a spreadsheet would run as a formula written quoted
        # (output/tables.py, docs/format.md); run.json says so, and baarda's readers undo it
        self.excel_safe = bool(excel_safe)
        self.final = check_output_folder(out, inputs)
        self._staging: Path | None = None  # made below, once no live run writes here
        self._refuse_if_busy(None)  # before anything is removed or made
        self.cleaned = remove_leftovers(self.final)
        if self.cleaned:
            check_output_folder(out, inputs)  # an earlier run moved back is checked too
        self.replaces = earlier_run(self.final)
        self.run_id = new_run_id()
        self.command = command
        self.started = datetime.now(UTC)
        self.warnings: list[str] = []
        parent = self.final.parent
        try:
            parent.mkdir(parents=True, exist_ok=True)
            self._staging = parent / f".{self.final.name}.{self.run_id}.partial"
            self._staging.mkdir()
        except OSError as e:
            raise place_error(self.final, e, "cannot write the output folder here") from None
        self._lock = _lock(self.path)
        self.done = False
        self.kept: list[str] = []
        self._refuse_if_busy(self.run_id)  # two that started at once: the later one

    @property
    def path(self) -> Path:
        """The staging folder: where the run writes."""
        assert self._staging is not None  # made in __init__
        return self._staging

    def _refuse_if_busy(self, before: str | None) -> None:
        """A ProjectError when a live run (its staging folder locked) writes the same folder:
        any (`before` None), or one whose id sorts before `before` (this run's staging
        folder is then discarded)."""
        busy = self._rival(before)
        if busy:
            if self._staging is not None:
                self.discard()
            raise ProjectError(str(self.final), f"another run ({busy}) is writing this "
                               "output folder now; wait until it ends or choose another "
                               "folder with -o")

    def _rival(self, before: str | None) -> str | None:
        """The id of a live run into the same folder (that started before `before`), None
        when there is none."""
        try:
            entries = list(self.final.parent.iterdir())
        except OSError:
            return None
        for p in sorted(entries):
            m = _LEFTOVER.fullmatch(p.name)
            if not m or m.group("name") != self.final.name or m.group("kind") != "partial" \
                    or p == self._staging or (before is not None and m.group("run") > before):
                continue
            fd = _lock(p)
            if fd is None and p.exists():
                return m.group("run")
            _unlock(fd)
        return None

    def describe(self) -> str:
        """Where the run went, for people: 'OUT' or 'OUT (replacing run X)'."""
        return str(self.given) + (f" (replacing {self.replaces})" if self.replaces else "")

    def file(self, name: str) -> Path:
        """Where to write `name` in this run (inside the staging folder)."""
        return self.path / name

    def __enter__(self) -> RunFolder:
        return self

    def __exit__(self, kind, value, tb) -> None:
        if kind is None:
            self.commit()
            return
        self.discard()
        if isinstance(value, OSError) and not isinstance(value, OutputError) and \
                self._inside(value.filename):
            raise self._output_error(value) from value
        if isinstance(value, OutputError) and self._inside(value.filename):
            raise self._output_error(value) from value.__cause__

    def _inside(self, filename) -> bool:
        if not isinstance(filename, (str, os.PathLike)):
            return False
        p = Path(filename)
        return p == self.path or self.path in p.parents

    def _output_error(self, e: OSError) -> OutputError:
        """The error of a write into the staging folder, for the file's place in the output
        folder (the staging folder is gone)."""
        name = Path(e.filename).relative_to(self.path)
        return OutputError(e.errno, e.strerror or str(e), str(self.given / name))

    def placed(self) -> bool:
        """Whether the output folder holds this run (its run.json names this run's id): read
        from the folder, so that an interruption at any moment of the move is told right."""
        try:
            doc = json.loads((self.final / MANIFEST).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return False
        return isinstance(doc, dict) and doc.get("run") == self.run_id

    def discard(self) -> None:
        """Remove the staging folder; the output folder is left as it was."""
        shutil.rmtree(self.path, ignore_errors=True)
        _unlock(self._lock)
        self._lock = None

    def commit(self) -> Path:
        """Write run.json and move the staging folder into place (replacing an earlier run's
        files; other files of the folder are kept: _carry_foreign); the output folder."""
        if self.done:
            return self.final
        files = {}
        for f in sorted(self.path.rglob("*")):
            if f.is_file():
                files[f.relative_to(self.path).as_posix()] = file_record(f)
        manifest: dict[str, object] = {
            "run": self.run_id, "baarda": package_version(),
            "started": self.started.isoformat(timespec="seconds"),
            "finished": datetime.now(UTC).isoformat(timespec="seconds"),
            "command": self.command, "files": files}
        if self.excel_safe:
            manifest["excel_safe"] = True
        try:
            (self.path / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n",
                                              encoding="utf-8")
        except OSError as e:
            self.discard()
            raise OutputError(e.errno, e.strerror, str(self.given / MANIFEST)) from e
        old, held = None, None
        try:
            if self.final.exists():
                check_output_folder(self.final)  # still one of ours
                self._carry_foreign()
                held = _lock(self.final)  # moved aside under a lock: not a leftover
                old = self.final.parent / f".{self.final.name}.{self.run_id}.old"
                os.replace(self.final, old)
            os.replace(self.path, self.final)
        except BaseException as e:
            if old is not None and old.exists() and not self.final.exists():
                os.replace(old, self.final)  # the earlier run back in its place
            elif old is not None and self.placed():  # interrupted as the run went in place
                shutil.rmtree(old, ignore_errors=True)
            _unlock(held)
            self.discard()
            if isinstance(e, OSError):
                raise OutputError(e.errno, e.strerror, str(self.given)) from e
            raise
        _unlock(self._lock)
        self._lock = None
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
            _unlock(held)
            if old.exists():
                self.warnings.append(f"could not remove the earlier run, moved aside to "
                                     f"{old}: remove it by hand")
        if self.kept:
            shown = ", ".join(self.kept[:5]) + (", ..." if len(self.kept) > 5 else "")
            self.warnings.append(f"kept {len(self.kept)} file(s) in {self.given} that no run "
                                 f"of baarda wrote there ({shown}); they may describe "
                                 f"{self.replaces or 'the earlier run'}")
        self.done = True
        return self.final

    def _carry_foreign(self) -> None:
        """Put the files of the output folder that no run wrote (`foreign_files`) into the
        staging folder, so that the swap keeps them; one the new run wrote too keeps the
        new run's file and the user's is put beside it as NAME.earlier."""
        for rel in foreign_files(self.final):
            dst = self.path / rel
            if os.path.lexists(dst):
                dst = dst.with_name(dst.name + ".earlier")
            _carry(self.final / rel, dst)
            self.kept.append(dst.relative_to(self.path).as_posix())


def earlier_run(folder: Path) -> str | None:
    """'run ID' of the run an existing output folder holds, 'an earlier run' for a folder
    written before run.json existed, None for a new or empty folder."""
    if not folder.is_dir() or not any(folder.iterdir()):
        return None
    try:
        return "run " + str(json.loads((folder / MANIFEST).read_text(encoding="utf-8"))["run"])
    except (OSError, ValueError, KeyError, TypeError):
        return "an earlier run"


@contextmanager
def staged(out: str | Path | RunFolder) -> Iterator[RunFolder]:
    """The run to write into: `out` itself when it is a RunFolder (its owner commits it),
    else a new run of the folder `out`, committed when the block ends."""
    if isinstance(out, RunFolder):
        yield out
        return
    with RunFolder(out, command=" ".join(sys.argv[:1])) as run:
        yield run
