"""Real navigation records the GEONET and synthetic sets lack: Galileo E14 and E18 (the two
satellites left in eccentric orbits, e = 0.16), QZSS J01-J03 (inclined, e = 0.075, sqrt(A) =
6493), a BeiDou GEO, from the RINEX 3.05 file of station ESBC (tests/data/README.md).

* the reader against the file's own text and against georinex (GPS and QZSS records; georinex
  1.16 reads no Galileo/BeiDou value of this file);
* satellite positions and clocks against RTKLIB's (rnx2rtkp -x 4 trace) at transmit times up to
  80 min from toe: for e = 0.16 the relativistic clock term reaches 1.2e-7 s (37 m) and
  sqrt(1 - e^2) differs from 1 - e^2/2 by 8e-5, so small-eccentricity shortcuts show;
* ephemeris selection at the edge of the fit interval (GPS 4 h, QZSS flag 0: 2 h, flag 1: 4 h),
  for an unhealthy satellite (E14/E18 were flagged in 2020), and between the I/NAV and F/NAV
  records of one toe.
"""
from __future__ import annotations

import shutil
import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest

from leonav_runtime.gnss import time as gtime
from leonav_runtime.gnss.ephemeris import OK, STALE, UNHEALTHY, is_bds_geo
from leonav_runtime.gnss.rinex_nav import read_rinex_nav
from leonav_runtime.orbits.broadcast import satellite_states
from tests.gnss_rinex3_synth import header_line

NAV = Path(__file__).parent / "data" / "rinex" / "ESBC00DNK_R_20201770000_cut_MN.rnx"
RNX2RTKP = shutil.which("rnx2rtkp")
needs_rtklib = pytest.mark.skipif(RNX2RTKP is None, reason="rnx2rtkp (Debian package rtklib) not installed")


def _nav():
    with warnings.catch_warnings():
        warnings.simplefilter("error")   # no record of the file is rejected
        return read_rinex_nav(NAV)


def _rows(nf, sat: str):
    d = nf.ephemerides.data
    return d[(d["system"] == sat[0]) & (d["prn"] == int(sat[1:]))]


def test_the_records_are_read_as_the_file_gives_them():
    nf = _nav()
    assert nf.counts["records"] == 9 and nf.counts["skipped_R"] == 1 and not nf.rejected
    e14 = _rows(nf, "E14")
    assert e14.size == 2 and np.all(e14["e"] == 1.668273569085e-01) and np.all(e14["sqrt_a"] == 5.289401033401e+03)
    # data sources (RINEX 3.05 Table A8): 517 = I/NAV E1-B + E5b, clock E5b,E1; 258 = F/NAV E5a, clock E5a,E1
    inav, fnav = e14[e14["data_sources"] == 517][0], e14[e14["data_sources"] == 258][0]
    assert fnav["af0"] == -1.061560469680e-03 and inav["af0"] == -1.061561808456e-03
    assert inav["tgd"] == fnav["tgd"] == -5.122274160385e-09           # BGD E5a/E1
    assert fnav["tgd2"] == 0.0 and inav["tgd2"] == -5.820766091347e-09  # BGD E5b/E1 (F/NAV has none: 0)
    assert fnav["health"] == 48 and inav["health"] == 390
    assert fnav["transmit"] == pytest.approx(float(gtime.nearest_week_time(362090.0, fnav["toe"])))
    assert inav["transmit"] == pytest.approx(float(gtime.nearest_week_time(362015.0, inav["toe"])))
    assert _rows(nf, "E18")["e"][0] == pytest.approx(0.16, abs=0.01)
    c05 = _rows(nf, "C05")[0]
    assert c05["geo"] and c05["toe"] - c05["toc"] == 0.0
    # BeiDou epochs are BDT: toc 2020-06-25 00:00:00 BDT is 00:00:14 GPST
    assert c05["toc"] == gtime.calendar_to_seconds(2020, 6, 25, 0, 0, 14.0)
    # header: IONOSPHERIC CORR as written (GPSA, GPSB, GAL)
    assert nf.iono["GPSA"] == (4.6566e-09, 1.4901e-08, -5.9605e-08, -1.1921e-07)
    assert nf.iono["GPSB"] == (8.1920e+04, 9.8304e+04, -6.5536e+04, -5.2429e+05)
    assert nf.iono["GAL"][:3] == (2.8250e+01, 7.8125e-03, 1.0071e-02)


GEORINEX = {"SVclockBias": "af0", "SVclockDrift": "af1", "SVclockDriftRate": "af2", "IODE": "iode", "Crs": "crs",
            "DeltaN": "delta_n", "M0": "m0", "Cuc": "cuc", "Eccentricity": "e", "Cus": "cus", "sqrtA": "sqrt_a",
            "Toe": "toe_sow", "Cic": "cic", "Omega0": "omega0", "Cis": "cis", "Io": "i0", "Crc": "crc",
            "omega": "omega", "OmegaDot": "omega_dot", "IDOT": "idot", "CodesL2": "codes_l2", "GPSWeek": "week",
            "L2Pflag": "l2p_flag", "SVacc": "accuracy_m", "health": "health", "TGD": "tgd", "IODC": "iodc"}


def test_gps_and_qzss_fields_against_georinex():
    gr = pytest.importorskip("georinex")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = gr.load(NAV)
    nf = _nav()
    for sat in ("G02", "J01", "J02", "J03"):
        row = _rows(nf, sat)[0]
        ref = ds.sel(sv=sat)
        k = int(np.flatnonzero(np.isfinite(ref["SVclockBias"].values))[0])
        for theirs, ours in GEORINEX.items():
            assert row[ours] == pytest.approx(float(ref[theirs].values[k]), rel=1e-12, abs=1e-30), (sat, ours)
        tx = float(ref["TransTime"].values[k])
        assert float(gtime.week_tow(row["transmit"])[1]) == tx
        fit = float(ref["FitIntvl"].values[k])
        assert row["fit_flag"] == (int(fit != 0) if sat[0] == "J" else int(fit > 4))


def _obs_text(epochs, sats) -> str:
    head = [
        header_line("     3.05           OBSERVATION DATA    M: MIXED", "RINEX VERSION / TYPE"),
        header_line("leonav test        leonav              20200625 000000 UTC", "PGM / RUN BY / DATE"),
        header_line("ESBC", "MARKER NAME"),
        header_line(f"{3585278.7:14.4f}{531971.3:14.4f}{5201387.9:14.4f}", "APPROX POSITION XYZ"),
        header_line("        0.0000        0.0000        0.0000", "ANTENNA: DELTA H/E/N"),
        header_line("G    1 C1C", "SYS / # / OBS TYPES"),
        header_line("E    1 C1C", "SYS / # / OBS TYPES"),
        header_line("J    1 C1C", "SYS / # / OBS TYPES"),
        header_line("C    1 C2I", "SYS / # / OBS TYPES"),
        header_line("  2020     6    25     0     0    0.0000000     GPS", "TIME OF FIRST OBS"),
        header_line("", "END OF HEADER"),
    ]
    body = []
    for t in epochs:
        y, mo, d, h, mi, s = gtime.gps_seconds_to_datetime(t).timetuple()[:6]
        body.append(f"> {y:04d} {mo:02d} {d:02d} {h:02d} {mi:02d}{float(s):11.7f}  0{len(sats):3d}")
        body += [f"{sat}{pr:14.3f}  " for sat, pr in sats]
    return "\n".join(head + body) + "\n"


_TRACE_SAT = {"G": 0, "E": 59, "J": 95, "C": 105}   # RTKLIB 2.4.3 satellite numbers: offset per system


@needs_rtklib
def test_eccentric_galileo_and_qzss_positions_and_clocks_match_rtklib(tmp_path):
    from tests.test_gnss_rtklib import _TRACE   # the trace line pattern of rnx2rtkp -x 4

    nf = _nav()
    cases = {"E14": (25_312_345.678,), "E18": (26_112_345.678,), "J01": (38_212_345.678,),
             "J02": (39_012_345.678,), "J03": (37_812_345.678,), "G02": (21_512_345.678,), "C05": (37_912_345.678,)}
    results = []
    for sat, (pr,) in cases.items():
        rec = _rows(nf, sat)[0]
        # from 2 min after toe (RTKLIB takes no Galileo record before its toe) to 80 or 50 min
        epochs = [rec["toe"] + dt for dt in (120.0, 1800.0, 4800.0 if sat[0] == "E" else 3000.0)]
        obs, out = tmp_path / f"{sat}.obs", tmp_path / f"{sat}.pos"
        obs.write_text(_obs_text(epochs, [(sat, pr)]))
        subprocess.run([RNX2RTKP, "-p", "0", "-m", "0", "-sys", "G,E,J,C", "-x", "4", "-o", str(out), str(obs), str(NAV)],
                       check=True, capture_output=True, timeout=120)
        for line in Path(str(out) + ".trace").read_text(errors="replace").splitlines():
            m = _TRACE.match(line)
            if m and any(float(m.group(k)) for k in (8, 9, 10)):
                y, mo, d, h, mi = map(int, m.groups()[:5])
                assert int(m.group(7)) == _TRACE_SAT[sat[0]] + int(sat[1:])
                results.append((sat, gtime.calendar_to_seconds(y, mo, d, h, mi, float(m.group(6))),
                                [float(m.group(k)) for k in (8, 9, 10)], float(m.group(11)) * 1e-9))
    assert {r[0] for r in results} == set(cases) and len(results) == 3 * len(cases)
    sats = np.array([r[0] for r in results])
    t = np.array([r[1] for r in results])
    eph = nf.ephemerides
    index, status = eph.select(np.array([s[0] for s in sats]), np.array([int(s[1:]) for s in sats]), t,
                               allow_unhealthy=True)
    assert np.all(status == OK)
    # two records of one toe: ours takes the later transmission (here the F/NAV one), RTKLIB 2.4.3
    # the I/NAV one; their orbits are the same, their clocks 1.3e-9 s apart: compare RTKLIB's
    gal = np.char.startswith(sats.astype(str), "E")
    assert np.all(eph.data["data_sources"][index[gal]] == 258)
    for k in np.flatnonzero(gal):
        index[k] = np.flatnonzero((eph.data["system"] == "E") & (eph.data["prn"] == int(sats[k][1:]))
                                  & (eph.data["data_sources"] == 517))[0]
    st = satellite_states(eph.data[index], t)
    dr = np.abs(st.r_ecef_m - np.array([r[2] for r in results])).max(axis=1)
    dc = np.abs(st.clock_bias_s - np.array([r[3] for r in results]))
    assert dr.max() < 0.005, dict(zip(sats, dr))
    assert dc.max() < 2e-12, dict(zip(sats, dc))
    # what the test is sensitive to: E14's relativistic term is tens of metres of range
    e14 = sats == "E14"
    assert np.abs(st.relativistic_s[e14]).max() * 299792458.0 > 10.0


def test_selection_at_the_edge_of_the_fit_interval():
    nf = _nav()
    eph = nf.ephemerides
    g02, j01 = _rows(nf, "G02")[0], _rows(nf, "J01")[0]
    assert g02["fit_s"] == 4 * 3600.0 and j01["fit_flag"] == 0 and j01["fit_s"] == 2 * 3600.0
    for rec, half in ((g02, 7200.0), (j01, 3600.0)):
        t = rec["toe"] + np.array([-half - 1e-3, -half, 0.0, half, half + 1e-3])
        _, status = eph.select(rec["system"], rec["prn"], t)
        assert list(status) == [STALE, OK, OK, OK, STALE], (rec["system"], rec["prn"])


def test_qzss_fit_flag_1_is_a_4_hour_interval(tmp_path):
    """IS-QZSS-PNT: fit interval flag 0 = 2 hours, 1 = more than 2 hours (used as 4 h). The J01
    record with its fit-interval field set to 1 (the only edit)."""
    lines = NAV.read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.startswith("J01 ")) + 7
    assert lines[k][23:42] == " 0.000000000000e+00"
    lines[k] = lines[k][:23] + " 1.000000000000e+00" + lines[k][42:]
    edited = tmp_path / "j01_fit1.rnx"
    edited.write_text("\n".join(lines) + "\n")
    eph = read_rinex_nav(edited).ephemerides
    j01 = eph.data[(eph.data["system"] == "J") & (eph.data["prn"] == 1)][0]
    assert j01["fit_flag"] == 1 and j01["fit_s"] == 4 * 3600.0
    _, status = eph.select("J", 1, j01["toe"] + np.array([7200.0, 7200.001]))
    assert list(status) == [OK, STALE]


def test_unhealthy_galileo_is_unhealthy_not_stale():
    nf = _nav()
    eph = nf.ephemerides
    toe = _rows(nf, "E14")[0]["toe"]
    index, status = eph.select("E", 14, toe + np.array([600.0, 6 * 3600.0]))
    assert list(status) == [UNHEALTHY, STALE] and list(index) == [-1, -1]


def test_beidou_geo_prns():
    """BeiDou GEO satellites: C01-C05 (BDS-2) and C59-C63 (BDS-3), BDS-SIS-ICD B1C/B2a and B3I."""
    prn = np.arange(1, 66)
    assert list(prn[is_bds_geo(prn)]) == [1, 2, 3, 4, 5, 59, 60, 61, 62, 63]
