"""u-blox RXM-RAWX logs -> observation rows, checked against pyubx2's decode of the same bytes."""
from __future__ import annotations

import numpy as np
import pytest

from leonav_runtime.gnss.observations import (FLAG_CP_VALID, FLAG_HALF_CYCLE, FLAG_PR_VALID, UBX_GNSS,
                                              UBX_SIGNALS, rawx_to_table)
from leonav_runtime.gnss.ubx_log import parse_ubx_bytes, read_ubx_log
from tests.conftest import shared_file

LOGS = {  # file: (RAWX epochs, measurements)
    "ubx/gpsd/ublox-zed-f9p_hpg1.11.log": (654, 17052),
    "ubx/gpsd/ublox-neo-m8t.log": (39, 507),
    "ubx/pyubx2/pygpsdata-RXMRAWX.log": (14, 314),
}


def pyubx2_rawx(path):
    pyubx2 = pytest.importorskip("pyubx2")
    rows = []
    with open(path, "rb") as f:
        for _raw, msg in pyubx2.UBXReader(f, protfilter=2, quitonerror=0):
            if msg is None or msg.identity != "RXM-RAWX":
                continue
            t = msg.week * 604800.0 + msg.rcvTow
            for i in range(1, msg.numMeas + 1):
                g = lambda name: getattr(msg, f"{name}_{i:02d}")  # noqa: E731
                rows.append((t, g("gnssId"), g("svId"), g("sigId"), g("prMes"), g("cpMes"), g("doMes"), g("cno"),
                             g("prStd"), g("prValid"), g("cpValid"), g("halfCyc")))
    return rows


@pytest.mark.parametrize("rel,expected", LOGS.items())
def test_rawx_rows_match_pyubx2(rel, expected):
    path = shared_file(rel)
    log = read_ubx_log(path)
    obs = log.observations
    ref = pyubx2_rawx(path)
    epochs, measurements = expected
    assert obs.counts["epochs"] == epochs and obs.counts["measurements"] == measurements == len(ref)
    # every measurement of these logs is a known signal with a valid pseudorange: one row each
    assert len(obs) == len(ref)
    t, gnss, sv, sig, pr, cp, do, cno, prstd, prvalid, cpvalid, half = map(np.array, zip(*ref))
    assert np.array_equal(obs.t_gps_s, t)
    assert list(obs.system) == [UBX_GNSS[g] for g in gnss]
    assert np.array_equal(obs.prn, sv)
    assert list(obs.signal) == [UBX_SIGNALS[(g, s)] for g, s in zip(gnss, sig)]
    assert np.array_equal(obs.pseudorange_m, np.where(prvalid == 1, pr, np.nan), equal_nan=True)
    assert np.array_equal(obs.carrier_phase_cyc, np.where(cpvalid == 1, cp, np.nan), equal_nan=True)
    assert np.array_equal(obs.doppler_hz, do)
    assert np.array_equal(obs.cn0_dbhz, cno.astype(float))
    assert np.array_equal(obs.sigma_pr_m[prvalid == 1], 0.01 * 2.0 ** prstd[prvalid == 1])
    assert np.array_equal(obs.has_flag(FLAG_PR_VALID), prvalid == 1)
    assert np.array_equal(obs.has_flag(FLAG_CP_VALID), cpvalid == 1)
    assert np.array_equal(obs.has_flag(FLAG_HALF_CYCLE), (cpvalid == 1) & (half == 0))
    assert len(log.ephemerides) == 0  # no GPS subframes in these logs


def test_f9p_log_systems_and_signals():
    obs = read_ubx_log(shared_file("ubx/gpsd/ublox-zed-f9p_hpg1.11.log")).observations
    s = obs.summary()
    assert set(s["rows_per_system"]) == {"G", "E", "C", "R"}
    assert set(s["rows_per_signal"]) == {"G1C", "G2L", "E1C", "E7Q", "C2I", "R1C", "R2C"}
    assert obs.epochs().size == 654 and np.all(np.diff(obs.epochs()) > 0.99)
    glo = obs.take(obs.system == "R")
    assert np.all((glo.freq_slot >= -7) & (glo.freq_slot <= 6))


def test_invalid_zero_and_nan_measurements_are_counted(monkeypatch):
    from leonav.hardware.records import RawxMeasurement, RxmRawx

    def meas(**kw):
        base = dict(gnss_id=0, sv_id=5, sig_id=0, freq_id=0, pseudorange_m=2.1e7, carrier_phase_cyc=1.1e8,
                    doppler_hz=-1200.0, cno_dbhz=40, locktime_s=10.0, pr_std_m=0.32, cp_std_cyc=0.004,
                    do_std_hz=0.02, pr_valid=True, cp_valid=True, half_cyc=True, sub_half_cyc=False)
        base.update(kw)
        return RawxMeasurement(**base)

    epoch = RxmRawx(0.0, 100.0, 2100, 18, True, False, 1, [
        meas(), meas(pr_valid=False), meas(pseudorange_m=0.0), meas(pseudorange_m=float("nan")),
        meas(gnss_id=4), meas(gnss_id=6, sv_id=255), meas(pr_valid=False, cp_valid=False, doppler_hz=float("nan")),
    ])
    obs = rawx_to_table([epoch], "x")
    c = obs.counts
    assert (c["measurements"], c["pr_invalid"], c["pr_nan_or_zero"], c["unknown_signal"],
            c["glonass_unknown_slot"], c["rows_without_values"]) == (7, 2, 2, 1, 1, 1)
    assert len(obs) == 4 and np.isfinite(obs.pseudorange_m).sum() == 1
    assert obs.t_gps_s[0] == 2100 * 604800.0 + 100.0


def test_garbage_bytes_do_not_stop_the_log():
    data = shared_file("ubx/gpsd/ublox-neo-m8t.log").read_bytes()
    k = len(data) // 2
    log = parse_ubx_bytes(data[:k] + b"\xb5\x62\x02\x15\xff\x00garbage" + data[k:], "x")
    assert log.observations.counts["epochs"] >= 38
    assert log.counts["framing_junk_bytes"] > 0
