"""Text files of every input as the readers take them, each problem a ProjectError naming
the file and the 1-based line: the encoding (`decode_text`, UTF-8 unless the user names
another), NUL bytes and control characters (`no_nul`), line ends (`split_lines`, `line_of`),
what a path is (`not_a_file`, `file_kind`), the head of a file, whole files and their lines
(`file_bytes`, `read_lines`, `whole_lines`, `whole_bytes`), and a file cut short
(`refuse_cut_short`).  The parsing of records and numbers is io/records.py.
"""

from __future__ import annotations

import errno
import os
import re
import stat
from pathlib import Path

from baarda.errors import ProjectError

ENCODING = "utf-8"  # of every text input unless the user names another (--encoding)


def is_utf8(encoding: str) -> bool:
    return encoding.lower().replace("_", "-") in ("utf-8", "utf8", "utf-8-sig")


def decode_text(data: bytes, path: str, encoding: str = ENCODING) -> str:
    """`data` as text (a UTF-8 byte-order mark is dropped); ProjectError naming the line and
    the byte that is not `encoding`, or the encoding that Python does not know."""
    if is_utf8(encoding):
        encoding = "utf-8-sig"
    try:
        text = data.decode(encoding)
        if encoding == "utf-8-sig":
            text = text.lstrip("\ufeff")  # a second byte-order mark (files joined)
        return no_nul(text, path)
    except LookupError:
        raise ProjectError(path, f"unknown text encoding '{encoding}' (e.g. utf-8, cp1252, "
                           "latin-1)") from None
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        name = encoding.replace("-sig", "")
        raise ProjectError(path, f"not {name} text: byte 0x{data[e.start]:02x} (save the "
                           "file as UTF-8, or name its encoding, e.g. --encoding cp1252)",
                           line) from None


#: a line end: LF, CRLF or CR, and CR blanks LF as one (MicMac's liaisons files end their
#: lines " \r \n": read as two ends, every line number after the first was 2N - 1)
LINE_END = re.compile(r"\r[ \t]*\n|\r|\n")


def line_of(text: str, index: int) -> int:
    """The 1-based line (as split_lines counts them) of the character at `index`."""
    return len(LINE_END.findall(text, 0, index)) + 1


#: characters no text input holds: NUL and the other C0 controls but tab, line ends, form
#: feed, vertical tab and DOS's end-of-file mark (ESC, BEL ... act on a terminal that prints
#: an id), DEL and the C1 controls
C0_DEL = "\x00-\x08\x0e-\x19\x1b-\x1f\x7f"  # the C0 controls refused, and DEL
CONTROL = re.compile(f"[{C0_DEL}\x80-\x9f]")


def no_nul(text: str, path: str, header: list[str] | None = None) -> str:
    """`text`, or ProjectError naming the line (and, for a CSV table with `header`, the
    column) of its first control character (CONTROL: NUL, the other C0 controls but tab,
    line ends, form feed, vertical tab and DOS's end-of-file mark, DEL, the C1 controls):
    text files hold none (a NUL: a damaged file, or a binary one), and inside an id it would
    make the id differ from the same id elsewhere (an ESC or BEL acts on a terminal)."""
    m = CONTROL.search(text)
    if m is None:
        return text
    k = m.start()
    line = line_of(text, k)
    start = max(text.rfind("\n", 0, k), text.rfind("\r", 0, k)) + 1
    field = text.count(",", start, k)
    column = header[field] if header is not None and line > 1 and field < len(header) else None
    if text[k] == "\x00":
        raise ProjectError(path, "a NUL byte (\\x00) in the text: a damaged or binary file "
                           "(ids and numbers are printable text)", line, column)
    raise ProjectError(path, f"a control character (\\x{ord(text[k]):02x}) in the text: ids "
                       "and numbers are printable text (an ESC or BEL printed to a terminal "
                       "acts on it)", line, column)


def split_lines(text: str) -> list[str]:
    """Lines without their ends (LF, CRLF, CR or CR blanks LF; no line after a final line
    end).  Unlike str.splitlines, form feeds, vertical tabs, U+2028 and the like are not
    line ends, so that line numbers are those an editor shows."""
    lines = LINE_END.split(text)
    if lines[-1] == "":
        lines.pop()
    return lines


_KINDS = ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"),
          (stat.S_ISDIR, "a folder"))


def file_kind(mode: int) -> str:
    """What a file of `mode` (os.stat) is, in words: 'a regular file', 'a folder', 'a FIFO
    (named pipe)', ..."""
    return next((name for test, name in _KINDS if test(mode)),
                "a regular file" if stat.S_ISREG(mode) else "not a regular file")


def not_a_file(path: str | Path, what: str = "file not found") -> str | None:
    """Why `path` cannot be read as a file (`what` when it does not exist; a folder, a FIFO,
    a device, a link loop, a name too long), None for a regular file (or a link to one).
    Only regular files are opened: a FIFO would block the reader."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return what
    except OSError as e:
        if e.errno == errno.ELOOP:
            return "is a symbolic link loop, not a file"
        return f"cannot be read ({e.strerror or e})"
    if stat.S_ISREG(st.st_mode):
        return None
    return f"is {file_kind(st.st_mode)}, not a regular file"


def file_head(path: str | Path, size: int = 4096, *, line: bool = False) -> bytes:
    """The first `size` bytes of a regular file (its first line only, with `line`), a UTF-8
    byte-order mark dropped; b"" for anything that is not a readable regular file.  For the
    readers' `detect`: sniffing never raises."""
    p = Path(path)
    if not p.is_file():
        return b""
    try:
        with open(p, "rb") as f:
            head = f.readline(size) if line else f.read(size)
    except OSError:
        return b""
    return head.removeprefix(b"\xef\xbb\xbf")


def first_line_starts(path: str | Path, prefix: bytes) -> bool:
    """Whether `path` is a file whose first line (after a byte-order mark) starts with
    `prefix`."""
    return file_head(path, 256, line=True).startswith(prefix)


def require_file(path: str | Path, what: str = "file not found") -> None:
    """ProjectError naming `path` unless it is a regular file (or a link to one): says
    what it is instead (missing: `what`; a folder, a FIFO, a link loop, ...)."""
    problem = not_a_file(path, what)
    if problem is not None:
        raise ProjectError(str(path), problem)


def file_bytes(path: str | Path, what: str = "file not found") -> bytes:
    """The bytes of a regular file; ProjectError naming it when it does not exist (`what`),
    is not a regular file (`not_a_file`) or cannot be read (permissions, ...)."""
    require_file(path, what)
    try:
        return Path(path).read_bytes()
    except OSError as e:
        raise ProjectError(str(path), f"cannot be read ({e.strerror or e})") from None


def read_lines(path: str | Path, encoding: str = ENCODING) -> list[str]:
    """Lines of a text file without line ends (CRLF, LF or CR); ProjectError if
    unreadable."""
    return split_lines(decode_text(file_bytes(path), str(path), encoding))


def whole_lines(path: str | Path, encoding: str = ENCODING, *,
                allow_empty: bool = False) -> list[str]:
    """read_lines of a data file that a program writes whole: ProjectError when it is empty
    (unless `allow_empty`) or its last line has no line end, the marks of a file cut short
    (a cut exactly at a line end cannot be seen: docs/formats.md)."""
    return split_lines(decode_text(whole_bytes(path, allow_empty=allow_empty), str(path),
                                   encoding))


def whole_bytes(path: str | Path, *, allow_empty: bool = False) -> bytes:
    """The bytes of a data file that a program writes whole, refused (as `whole_lines`
    refuses it) when empty or cut short in its last line; not decoded."""
    data = file_bytes(path)
    if not data.strip() and not allow_empty:
        raise ProjectError(str(path), "the file is empty: cut short, or not written "
                           "(it must hold at least one record)")
    refuse_cut_short(str(path), not data or data[-1:] in (b"\n", b"\r"),
                     data.count(b"\n") + 1)
    return data


def is_number(text: str) -> bool:
    """Whether float() reads `text`."""
    try:
        float(text)
        return True
    except ValueError:
        return False


def _decimals(text: str) -> int | None:
    """Digits after the decimal point of a number as written (None: not a plain number)."""
    t = text.strip().lower()
    if not is_number(t) or "e" in t or "n" in t:
        return None
    return len(t.split(".", 1)[1]) if "." in t else 0


def refuse_cut_short(path: str, ends_a_line: bool, last_line: int,
                     rows: list[list[str]] | None = None) -> None:
    """The one rule for a file cut short in the middle of its last line (`last_line`): a
    ProjectError naming that line when the text does not end with a line end and
    - `rows` is None (a file a program writes whole, `whole_lines`): always;
    - else (its data rows, as given): its last row has fewer fields than the row before, or
      its last value has fewer decimals than that column has in every other row (a
      program's fixed format, at least 3 rows; '11' where the column reads '11933.7743').
    A cut exactly at a line end cannot be seen (docs/formats.md)."""
    if ends_a_line:
        return
    if rows is None:
        raise ProjectError(path, "the last line has no line end: the file is cut short "
                           "(a program writes every line whole)", last_line)
    if len(rows) < 2:
        return
    last, before = rows[-1], rows[-2]
    said = (f"the file ends in the middle of line {last_line} (no line end after it, and "
            "{}): a file cut short?")
    if len(last) < len(before):
        raise ProjectError(path, said.format(f"{len(last)} fields where the line before "
                                             f"has {len(before)}"), last_line)
    k = len(last) - 1
    if len(rows) < 3 or any(len(r) <= k for r in rows[:-1]):
        return
    column = {_decimals(r[k]) for r in rows[:-1]}
    d = _decimals(last[k])
    if len(column) != 1 or d is None:
        return
    (places,) = column
    if places is not None and d < places:
        raise ProjectError(path, said.format(f"its last value '{last[k].strip()}' has {d} "
                                             f"decimals where every other line has "
                                             f"{places}"), last_line)
