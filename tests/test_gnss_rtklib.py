"""Outside reference: RTKLIB (rnx2rtkp) on the GEONET 0759/3040 data and on RINEX 3 text.

* Our least-squares position from our satellite positions/clocks against RTKLIB's
  single-point solutions committed in tests/data/rtklib (exact commands in its README).
* When rnx2rtkp is installed: it is re-run (same output as the fixtures), and its trace
  (-x 4 prints every satellite position and clock it used) is compared with ours, for GPS
  (GEONET) and for Galileo, BeiDou MEO and BeiDou GEO (RINEX 3 text from
  tests/gnss_rinex3_synth.py).
"""
from __future__ import annotations

import re
import shutil
import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest

from leonav_runtime.orbits.geometry import geodetic_to_ecef
from leonav_runtime.gnss import time as gtime
from leonav_runtime.gnss.ephemeris import OK
from leonav_runtime.gnss.rinex_nav import read_rinex_nav
from leonav_runtime.gnss.rinex_obs import read_rinex_obs
from leonav_runtime.orbits.broadcast import satellite_states
from tests import gnss_rinex3_synth as synth
from tests.conftest import shared_file
from tests.gnss_spp import single_point

FIXTURES = Path(__file__).parent / "data" / "rtklib"
STATIONS = ("0759", "3040")
RNX2RTKP = shutil.which("rnx2rtkp")
needs_rtklib = pytest.mark.skipif(RNX2RTKP is None, reason="rnx2rtkp (Debian package rtklib) not installed")


def read_pos(path: Path) -> dict[float, tuple[np.ndarray, int]]:
    """rnx2rtkp .pos (week tow lat lon h Q ns ...) -> {t_gps_s: (r_ecef_m, ns)}."""
    out = {}
    for line in path.read_text().splitlines():
        if line.startswith("%") or not line.strip():
            continue
        p = line.split()
        t = float(gtime.gps_seconds(int(p[0]), float(p[1])))
        lat, lon, h = np.radians(float(p[2])), np.radians(float(p[3])), float(p[4])
        out[round(t, 1)] = (np.asarray(geodetic_to_ecef(lat, lon, h), float).reshape(3), int(p[6]))
    return out


def data(station: str):
    obs = read_rinex_obs(shared_file(f"gnss_rinex/{station}0920.05o"))
    nav = read_rinex_nav(shared_file(f"gnss_rinex/{station}0920.05n")).ephemerides
    return obs, nav


@pytest.mark.parametrize("station", STATIONS)
def test_wls_matches_rtklib_single_point(station):
    obs, nav = data(station)
    ours = single_point(obs, nav, mask_deg=10.0)
    ref = read_pos(FIXTURES / f"{station}0920.05.pos")
    assert len(ref) == 120 and len(ours) == 120
    diffs, nsat_mismatch = [], 0
    for t, (r, _clk, n) in ours.items():
        r_ref, n_ref = ref[round(t, 1)]
        diffs.append(np.linalg.norm(r - r_ref))
        nsat_mismatch += n != n_ref
    diffs = np.array(diffs)
    # printed to 1e-9 deg / 0.1 mm: the two solutions agree to that print resolution
    assert diffs.max() < 0.005, f"max |ours - RTKLIB| = {diffs.max():.4f} m"
    assert nsat_mismatch == 0
    # and the unweighted variant stays within metres (the weights are almost equal)
    plain = single_point(obs, nav, mask_deg=10.0, weighted=False)
    worst = max(np.linalg.norm(plain[t][0] - ref[round(t, 1)][0]) for t in plain)
    assert worst < 3.0


@needs_rtklib
@pytest.mark.parametrize("station", STATIONS)
def test_rnx2rtkp_rerun_reproduces_the_fixture(station, tmp_path):
    o = shared_file(f"gnss_rinex/{station}0920.05o")
    n = shared_file(f"gnss_rinex/{station}0920.05n")
    out = tmp_path / f"{station}.pos"
    subprocess.run([RNX2RTKP, "-p", "0", "-m", "10", "-sys", "G", "-o", str(out), str(o), str(n)],
                   check=True, capture_output=True, timeout=120)
    body = [ln for ln in out.read_text().splitlines() if not ln.startswith("%")]
    fixture = [ln for ln in (FIXTURES / f"{station}0920.05.pos").read_text().splitlines() if not ln.startswith("%")]
    assert body == fixture


_TRACE = re.compile(r"^4 (\d+)/(\d+)/(\d+) (\d+):(\d+):([\d.]+) sat=\s*(\d+) rs=\s*(\S+)\s+(\S+)\s+(\S+) dts=\s*(\S+)")


def rtklib_sat(n: int) -> tuple[str, int]:
    """RTKLIB 2.4.3 satellite number -> (system, prn): GPS 1-32, GLO 33-59, GAL 60-95, QZS 96-105, BDS 106-."""
    if n <= 32:
        return "G", n
    if 60 <= n < 96:
        return "E", n - 59
    if n >= 106:
        return "C", n - 105
    return "?", n


def trace_states(obs: Path, nav: Path, systems: str, tmp_path: Path):
    out = tmp_path / "x.pos"
    subprocess.run([RNX2RTKP, "-p", "0", "-m", "0", "-sys", systems, "-x", "4", "-o", str(out), str(obs), str(nav)],
                   check=True, capture_output=True, timeout=300)
    rows = []
    for line in Path(str(out) + ".trace").read_text(errors="replace").splitlines():
        m = _TRACE.match(line)
        if m:
            y, mo, d, h, mi = map(int, m.groups()[:5])
            system, prn = rtklib_sat(int(m.group(7)))
            rs = [float(m.group(k)) for k in (8, 9, 10)]
            if any(rs):
                rows.append((gtime.calendar_to_seconds(y, mo, d, h, mi, float(m.group(6))), system, prn, *rs,
                             float(m.group(11)) * 1e-9))
    return rows


def compare_trace(rows, nav):
    t = np.array([r[0] for r in rows])
    system = np.array([r[1] for r in rows])
    prn = np.array([r[2] for r in rows])
    rs = np.array([r[3:6] for r in rows])
    dts = np.array([r[6] for r in rows])
    index, status = nav.select(system, prn, t)
    assert np.all(status == OK)
    st = satellite_states(nav.data[index], t)
    # trace epochs are printed to 1 us (4 mm of satellite motion), rs to 1 mm, dts to 1 ps
    dr = np.abs(st.r_ecef_m - rs).max(axis=1)
    dc = np.abs(st.clock_bias_s - dts)
    return system, dr, dc


@needs_rtklib
def test_gps_satellite_positions_and_clocks_match_rtklib_trace(tmp_path):
    obs = shared_file("gnss_rinex/07590920.05o")
    nav_path = shared_file("gnss_rinex/07590920.05n")
    rows = trace_states(obs, nav_path, "G", tmp_path)
    assert len(rows) == 948  # one per L1 pseudorange row of the file
    _system, dr, dc = compare_trace(rows, read_rinex_nav(nav_path).ephemerides)
    assert dr.max() < 0.005, dr.max()
    assert dc.max() < 2e-12, dc.max()


@needs_rtklib
def test_galileo_and_beidou_meo_geo_match_rtklib_trace(tmp_path):
    nav_path, obs_path = tmp_path / "t.nav", tmp_path / "t.obs"
    nav_path.write_text(synth.nav_text())
    obs_path.write_text(synth.obs_text())
    rows = trace_states(obs_path, nav_path, "G,E,C", tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        nav = read_rinex_nav(nav_path).ephemerides
    system, dr, dc = compare_trace(rows, nav)
    got = {(r[1], r[2]) for r in rows}
    # RTKLIB 2.4.3 uses Galileo I/NAV records only, and none before toe: E11 at the last epoch
    assert {("G", 5), ("E", 11), ("C", 11), ("C", 1)} <= got
    assert dr.max() < 0.005, dr.max()
    assert dc.max() < 2e-12, dc.max()
