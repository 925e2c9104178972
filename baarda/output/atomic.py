"""Atomic output: write to a temporary file beside the target, then rename.  A write that
fails (disk full, file too large, no permission) is an OutputError naming the target.

A target is written only where it is absent or a regular file; a symbolic link to one is
written through (the file it names is replaced, the link stays).  A FIFO, a device, a socket,
a folder, a link loop or a dangling link whose folder is missing are refused (ProjectError,
exit 2) naming the target: renaming over them would replace the node itself."""

from __future__ import annotations

import os
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from baarda.errors import OutputError, ProjectError
from baarda.io.text_files import file_kind

#: how many symbolic links a target may pass through (Linux's own limit)
MAX_LINKS = 40

def output_target(path: str | os.PathLike) -> Path:
    """The file that writing `path` replaces: `path` itself, or the file its symbolic links
    lead to; a ProjectError naming `path` when that is not absent or a regular file (module
    docstring)."""
    given = Path(path)
    target = given
    for _ in range(MAX_LINKS):
        try:
            st = os.lstat(target)
        except FileNotFoundError:
            if target != given and not target.parent.is_dir():
                raise ProjectError(str(given), f"is a symbolic link to {target}, whose folder "
                                   "does not exist; choose another file with -o") from None
            return target
        except OSError as e:
            raise ProjectError(str(given), f"cannot be written ({e.strerror}); choose "
                               "another file with -o") from None
        if stat.S_ISLNK(st.st_mode):
            target = target.parent / os.readlink(target)
            continue
        if not stat.S_ISREG(st.st_mode):
            via = "" if target == given else f" (a link to {target})"
            raise ProjectError(str(given), f"is {file_kind(st.st_mode)}{via}: a result is "
                               "written only to a regular file; choose another file with -o")
        return target
    raise ProjectError(str(given), "is a symbolic link loop (or a chain of more than "
                       f"{MAX_LINKS} links); choose another file with -o")


@contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "w", **kwargs) -> Iterator:
    """Open a temporary file next to `path`; on success it replaces `path` in one rename.
    An OSError of creating, writing or renaming is re-raised as an OutputError for `path`."""
    path = output_target(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as e:
        raise _output_error(e, path) from e
    try:  # the replaced file's permissions, else the usual ones (mkstemp makes 0600)
        perms = stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        perms = 0o666 & ~umask
    os.chmod(tmp, perms)
    try:
        with os.fdopen(fd, mode, **kwargs) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as e:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(e, OSError) and not isinstance(e, OutputError):
            raise _output_error(e, path) from e
        raise


def _output_error(e: OSError, path: Path) -> OutputError:
    return OutputError(e.errno, e.strerror or str(e), str(path))


def write_text(path: str | os.PathLike, text: str) -> None:
    with atomic_open(path, "w", encoding="utf-8", newline="") as f:
        f.write(text)


def write_bytes(path: str | os.PathLike, data: bytes) -> None:
    with atomic_open(path, "wb") as f:
        f.write(data)
