"""Ids with control characters (issue 43): an ESC or BEL in an id was printed raw to the
terminal (an OSC sequence retitled it); every text input refuses them at read time, naming
the file, the line and (in a CSV table) the column, as it refuses NUL."""

import shutil
from pathlib import Path

import pytest

from baarda.cli import main

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "examples" / "demo"
SXB = ROOT / "tests" / "data" / "dbat_sxb_aerial" / "dbat_script"


@pytest.mark.parametrize("char", ["\x1b]0;pwned\x07", "\x07", "\x1b", "\x7f", "\x9b"])
def test_a_control_character_in_a_native_id(tmp_path, capsys, char):
    d = tmp_path / "demo"
    shutil.copytree(DEMO, d)
    p = d / "image_points.csv"
    lines = p.read_text().splitlines()
    lines[3] = lines[3].replace(",", char + ",", 1)  # into the photo id
    p.write_text("\n".join(lines) + "\n")
    assert main(["adjust", str(d), "-o", str(tmp_path / "o"), "-q"]) == 2
    err = capsys.readouterr().err
    assert f"{p}, line 4, column 'photo': a control character (\\x{ord(char[0]):02x})" in err
    assert "\x1b" not in err and "\x07" not in err


def test_a_control_character_in_a_dbat_id(tmp_path, capsys):
    d = tmp_path / "s"
    shutil.copytree(SXB, d)
    p = d / "measurements" / "markpts.txt"
    lines = p.read_text().splitlines()
    n = next(i for i, s in enumerate(lines) if s and not s.startswith("#"))
    lines[n] = "\x1b[31m" + lines[n]
    p.write_text("\n".join(lines) + "\n")
    assert main(["convert", str(d / "sxb.xml"), "-o", str(tmp_path / "o")]) == 2
    assert f"{p}, line {n + 1}: a control character (\\x1b)" in capsys.readouterr().err


def test_tabs_form_feeds_and_line_ends_stay_accepted(tmp_path):
    from baarda.io.text_files import no_nul

    assert no_nul("a\tb\r\nc\fd\ve\x1a", "f") == "a\tb\r\nc\fd\ve\x1a"


@pytest.mark.parametrize("kind", ["photomodeler", "bal"])
def test_a_byte_order_mark_before_a_photomodeler_or_bal_file(tmp_path, kind):
    """docs/formats.md: a UTF-8 byte-order mark is always accepted; these two said 'format
    not recognised'."""
    from baarda.io.formats import detect

    if kind == "bal":  # the header is what recognises a BAL file
        data = b"2 2 4\n0 0 1 2\n1 0 1 2\n0 1 3 4\n1 1 3 4\n"
    else:
        data = (ROOT / "tests" / "data" / "dbat_sxb_aerial" / "photomodeler_export" /
                "wsmart-no-orient-pmexport.txt").read_bytes()
    p = tmp_path / "with_bom.txt"
    p.write_bytes(b"\xef\xbb\xbf" + data)
    assert detect(p) == kind
