"""`leonav beacons --carrier`: carrier phase of the associated tones beside the Doppler-rate output.

The outside reference is the pipeline's own, independent frequency measurement (STFT ridge
and local quadratic fit, doppler_rate_measurements.csv): the loop's Doppler and rate must
agree with it, and the accumulated phase must advance by the integral of the loop's Doppler.
"""
from __future__ import annotations

import csv
import json

import numpy as np
from scipy.integrate import simpson

from leonav_runtime.cli import main
from tests.conftest import shared_file


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_carrier_option_writes_phase_next_to_the_doppler_rate(tmp_path, capsys):
    tle = shared_file("tle/starlink_2026-02-23.txt")
    out = tmp_path / "out"
    rc = main(["beacons", str(tmp_path / "sim.cu8"), "--simulate", "--tle", str(tle), "--duration", "5",
               "--sim-rate", "1e6", "--band", "1e6", "--n-sats", "2", "--cn0", "35", "--no-figures", "--carrier",
               "--start", "2026-02-23T06:00:00Z", "--out", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "carrier: 2 tone(s) tracked" in text
    cols = (out / "carrier_phase.columns.txt").read_text()
    assert "phase_cycles [cycles]" in cols and "doppler_rate_hz_s [Hz/s]" in cols
    carrier = _rows(out / "carrier_phase.csv")
    meas = _rows(out / "doppler_rate_measurements.csv")
    assert {r["norad_id"] for r in carrier} == {r["norad_id"] for r in meas} and len(meas) >= 4
    for nid in {r["norad_id"] for r in meas}:
        c = [r for r in carrier if r["norad_id"] == nid]
        t = np.array([float(r["t_s"]) for r in c])
        locked = np.array([r["locked"] == "1" for r in c])
        assert locked[t >= 1.0].all() and not any(r["slip"] == "1" for r in c)
        phase = np.array([float(r["phase_cycles"]) if r["phase_cycles"] else np.nan for r in c])
        dop = np.array([float(r["doppler_hz"]) if r["doppler_hz"] else np.nan for r in c])
        rate = np.array([float(r["doppler_rate_hz_s"]) if r["doppler_rate_hz_s"] else np.nan for r in c])
        for m in (r for r in meas if r["norad_id"] == nid):
            k = int(np.argmin(np.abs(t - float(m["t_s"]))))
            assert abs(t[k] - float(m["t_s"])) < 1e-6
            assert abs(dop[k] - float(m["doppler_hz"])) < 5.0                      # Hz, of ~+-100 kHz
            drift = float(m["lo_drift_hz_s"])                                      # removed from the pipeline's
            assert abs(rate[k] - (float(m["doppler_rate_hz_s"]) + drift)) < 2.0   # Hz/s
        # phase advance over 1 s = integral of the baseband frequency, doppler - (rf_center - f_c)
        shift = json.loads((out / "summary.json").read_text())["capture"]["rf_center_hz"] - 11.325e9
        for a in np.nonzero(np.isfinite(phase) & np.isfinite(dop) & (t <= t.max() - 1.0))[0][::5]:
            b = a + 10
            if not np.isfinite(dop[a:b + 1]).all():
                continue
            integral = simpson(dop[a:b + 1] - shift, x=t[a:b + 1])   # exact for a cubic phase
            assert abs((phase[b] - phase[a]) - integral) < 0.1     # cycles, of ~1e5 in that second


def test_aiding_from_a_result_and_a_tone_the_capture_cannot_hold():
    import datetime as dt
    import types
    from pathlib import Path

    from leonav_runtime.beacons import carrier_hook
    from leonav_runtime.beacons.associate import Association
    from leonav_runtime.beacons.capture_io import CaptureInfo
    from leonav_runtime.beacons.predict import Predictions
    from leonav_runtime.beacons.ridges import Ridge

    fs = 1e6
    t = np.arange(-2.0, 8.01, 0.5)
    doppler = np.stack([20e3 - 1500.0 * t, 480e3 + 5000.0 * t])   # B's tone leaves the band (0.45 fs)
    pred = Predictions(dt.datetime(2026, 2, 23, tzinfo=dt.timezone.utc), t, ["A", "B"], np.array([1, 2]),
                       doppler, np.stack([-1500.0 + 0 * t, 0 * t]), np.ones((2, t.size)), np.array([0, 1]))
    rt = np.arange(0.1, 5.9, 0.016)
    ridges = [Ridge(rt, 20e3 - 1500.0 * rt - 35e3 + 3.0 * np.sin(rt), np.zeros(rt.size), 0),
              Ridge(rt[:60], 440e3 + 5000.0 * rt[:60], np.zeros(60), 1)]
    assoc = [Association(0, "associated", "", 0, "A", 1), Association(1, "associated", "", 1, "B", 2)]
    info = CaptureInfo(Path("x.cu8"), "cu8", fs, 1.575e9, 9.75e9, None, int(6 * fs))
    res = types.SimpleNamespace(predictions=pred, ridges=ridges, associations=assoc, info=info)
    skipped: list[str] = []
    out = carrier_hook.aidings(res, skipped=skipped)
    assert [a.norad_id for _, a, _ in out] == [1]
    aid = out[0][2]
    # the prediction's shape plus the ridge's median offset (-35 kHz here, the sine's median ~0)
    assert np.allclose(aid.at(np.array([1.0, 3.0])), 20e3 - 1500.0 * np.array([1.0, 3.0]) - 35e3, atol=3.0)
    assert len(skipped) == 1 and skipped[0].startswith("ridge 1 (B): predicted at") and "cannot hold" in skipped[0]
    line = carrier_hook.summary_line([], skipped)
    assert line.splitlines()[1].startswith("carrier: left out: ridge 1 (B)")
