"""GST sigmas and RMC velocities of a real u-blox ZED-F9P log on the fix table, and what a
checksum-valid sentence with an impossible time or value does there: counted and left out (its
epoch falls back to the HDOP sigma / no velocity), never a crash. pynmea2 hands an unreadable
time back as its text, which the table used to treat as a time."""
from __future__ import annotations

import math

import numpy as np
import pynmea2
import pytest

from leonav.hardware.gnss.reader import GnssReader
from leonav.hardware.records import GnssFix
from leonav_runtime.replay.gnss_table import fix_table
from tests.conftest import shared_file
from tests.test_nmea_fields import sentence

LOG = "nmea/gpsd/ublox-zed-f9p-nmea.log"


def _table(path):
    records = list(GnssReader(str(path)))
    fixes = [r for r in records if isinstance(r, GnssFix)]
    f0 = fixes[0]
    notes: list[str] = []
    table, counts = fix_table(records, lambda t: t, f0.utc.timestamp(), (f0.lat_rad, f0.lon_rad, f0.hmsl_m), notes)
    return table, counts, notes


def _lines(kind: str) -> list[str]:
    return [x.decode().rstrip("\r") for x in shared_file(LOG).read_bytes().split(b"\n") if x[3:6] == kind.encode()]


def _rewrite(tmp_path, kind: str, nth: int, field: int, value: str):
    """The log with field `field` of its `nth` `kind` sentence replaced and the checksum redone."""
    lines = shared_file(LOG).read_bytes().split(b"\n")
    seen = -1
    for i, line in enumerate(lines):
        if line[3:6] == kind.encode():
            seen += 1
            if seen == nth:
                body = line.rstrip(b"\r")[1:].split(b"*")[0].decode().split(",")
                body[field] = value
                lines[i] = sentence(",".join(body)).rstrip(b"\n")
                break
    path = tmp_path / "log.nmea"
    path.write_bytes(b"\n".join(lines))
    return path


def test_the_real_log_gives_every_fix_its_gst_sigma_and_rmc_velocity():
    table, counts, notes = _table(shared_file(LOG))
    n = table.t.size
    assert n > 20 and counts["fix_sigma_source"] == {"GST": n} and counts["gst_rmc_unreadable"] == 0, counts
    gst = [pynmea2.parse(x) for x in _lines("GST")]    # pynmea2 read straight from the text: the reference
    rmc = [pynmea2.parse(x) for x in _lines("RMC")]
    assert len(gst) == len(rmc) == n
    assert np.array_equal(table.sigma_enu_m, [[float(m.std_dev_longitude), float(m.std_dev_latitude),
                                                float(m.std_dev_altitude)] for m in gst])
    speed = np.array([float(m.spd_over_grnd) * 1852.0 / 3600.0 for m in rmc])   # knots; no course: north
    assert np.allclose(table.v_en_mps, np.c_[np.zeros(n), speed], rtol=0, atol=1e-12)
    assert not [x for x in notes if "GST/RMC" in x]


@pytest.mark.parametrize("kind, field, value", [
    ("GST", 1, "256000.00"),      # hour 25: pynmea2 returns the text
    ("GST", 6, "2.x"),            # a sigma that is not a number
    ("GST", 1, ""),               # no time: no epoch to match
    ("RMC", 1, "256000.00"),
])
def test_an_unreadable_gst_or_rmc_is_counted_and_its_epoch_falls_back(tmp_path, kind, field, value):
    clean, _, _ = _table(shared_file(LOG))
    table, counts, notes = _table(_rewrite(tmp_path, kind, 3, field, value))
    assert counts["gst_rmc_unreadable"] == 1, counts
    assert any("1 GST/RMC sentence(s) with an empty or unreadable" in x for x in notes), notes
    if kind == "GST":
        assert table.t.size == clean.t.size
        assert counts["fix_sigma_source"]["GST"] == clean.t.size - 1 and sum(counts["fix_sigma_source"].values()) \
            == clean.t.size, counts
    else:   # the RMC also dates the fixes: a bad one is the decoder's to reject; its epoch has no velocity
        assert np.sum(~np.isfinite(table.v_en_mps[:, 0])) == 1
        assert math.isclose(np.nanmax(np.abs(table.v_en_mps)), np.max(np.abs(clean.v_en_mps)), abs_tol=0.05)
