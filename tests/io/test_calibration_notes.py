"""Issue 41: the readers' notes on the calibration say what the run does.  A DBAT script's
or an AICON protocol's self-calibration is the input's choice: with --calibrate (here the
API's calibrate=) the run holds or frees other parameters, and no note may still say the
input's parameters are estimated (DBAT: 'the script estimates ...: self-calibration',
AICON: 'estimating c, x0, ...' and 'the estimated camera parameters ... taken from it')."""

from pathlib import Path

import pytest

import baarda

ROOT = Path(__file__).resolve().parents[2]
DBAT = ROOT / "tests" / "data" / "dbat_camcal_closerange" / "dbat_script" / "camcaldemo.xml"
AICON = ROOT / ".." / "shared" / "data" / "aicon_jaicov_closerange"



def test_dbat_calibrate_none_drops_the_scripts_self_calibration_note():
    b = baarda.read(DBAT)
    said = [n for n in b.notes if "the script estimates the interior orientation" in n]
    assert len(said) == 1 and "c, x0, y0, b1, k1, k2, k3, p1, p2" in said[0]
    none = baarda.read(DBAT, calibrate="none")
    assert all(f == () for f in none.settings.calibration_free)
    assert not [n for n in none.notes if "estimates" in n or "estimated" in n]
    assert any("camera model 'dbat3'" in n for n in none.notes)  # the model still is
    c = baarda.read(DBAT, calibrate="c")
    assert c.settings.calibration_free == (("c",),)
    assert not [n for n in c.notes if "the script estimates" in n]


@pytest.mark.skipif(not (AICON / "example.phc").is_file(), reason="AICON example not found")
def test_aicon_calibrate_none_drops_the_protocols_calibration_note():
    b = baarda.read(AICON / "example.obc")
    said = [n for n in b.notes if "estimate" in n]
    assert len(said) == 1 and "c, x0, y0, a1, a2, b1, b2" in said[0]
    assert "example.htm" in said[0]
    none = baarda.read(AICON / "example.obc", calibrate="none")
    assert all(f == () for f in none.settings.calibration_free)
    assert not [n for n in none.notes if "estimat" in n]
    assert any("a-priori sigmas of the image coordinates taken from it" in n
               for n in none.notes)  # the protocol's sigmas still are used
