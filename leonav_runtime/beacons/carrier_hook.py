"""Carrier phase of a processed capture's associated tones (`leonav beacons --carrier`).

After association (`pipeline.process_capture`), every associated ridge (each tone of a
satellite's comb) gets an aiding curve: the satellite's predicted Doppler from the element
sets (`Predictions`, LO-free) plus one constant, the median over the ridge of its measured
baseband frequency minus that prediction (the LO offset, the tone's place in the comb and
the tuning; a few Hz from the STFT ridge, well inside the loop's +-1 kHz acquisition). A
second pass over the capture (`carrier.track_tones`, all tones at once) gives the carrier
phase per 0.1 s epoch, written to carrier_phase.csv beside doppler_rate_measurements.csv.
"""
from __future__ import annotations

import datetime as _dt
import math
from pathlib import Path
from typing import Callable

import numpy as np

from leonav_runtime.beacons import capture_io
from leonav_runtime.beacons.carrier import CarrierConfig, CarrierTrack, track_tones
from leonav_runtime.beacons.carrier_front import Aiding
from leonav_runtime.common.errors import UserInputError

AID_STEP_S = 0.05
MIN_RIDGE_POINTS = 8

CARRIER_COLUMNS = [
    ("t_s", "s", "epoch, receiver time since the first sample"),
    ("epoch_utc", "ISO 8601", "epoch in UTC (capture start + t_s)"),
    ("norad_id", "-", "satellite of the tone"),
    ("name", "-", "satellite name"),
    ("ridge_id", "-", "ridge number in associations.csv"),
    ("tone_index", "-", "tone in the channel's comb (0 = centre), empty when unknown"),
    ("phase_cycles", "cycles", "accumulated carrier phase at baseband (rises with the frequency: its change is "
                               "-delta range / wavelength plus LO terms); empty when not locked; one ambiguity "
                               "per arc"),
    ("sigma_phase_cycles", "cycles", "thermal 1-sigma, sqrt(B_n/(C/N0) (1 + 1/(2 T C/N0))) / 2 pi"),
    ("locked", "0/1", "phase lock held over the epoch"),
    ("slip", "0/1", "a new arc starts here: relock after a loss or a detected cycle slip"),
    ("arc", "-", "continuous-phase arc number (-1 when not locked)"),
    ("cn0_dbhz", "dB-Hz", "estimated carrier-to-noise density"),
    ("doppler_hz", "Hz", "loop frequency + rf_center - f_c (LO offset included, as in "
                         "doppler_rate_measurements.csv); empty unless locked over +-0.25 s"),
    ("doppler_rate_hz_s", "Hz/s", "loop frequency rate (common LO drift not removed)"),
]


def aidings(res, step_s: float = AID_STEP_S, skipped: list | None = None) -> list[tuple[object, object, Aiding]]:
    """(ridge, association, aiding) for every associated ridge with enough points; a tone the
    capture cannot hold (predicted beyond 0.45 fs) is left out with its reason in `skipped`."""
    pred = res.predictions
    out = []
    skipped = [] if skipped is None else skipped
    if pred is None or pred.t_s.size < 4:
        return out
    duration = res.info.duration_s
    t = np.arange(-2 * step_s, duration + 3 * step_s, step_s)
    t = t[(t >= pred.t_s[0]) & (t <= pred.t_s[-1])]
    curves = pred.at(t)[0]
    for ridge, a in zip(res.ridges, res.associations):
        if a.status != "associated" or a.sat_row < 0 or ridge.t_s.size < MIN_RIDGE_POINTS:
            continue
        on_ridge = pred.at(ridge.t_s)[0][a.sat_row]
        offset = float(np.median(ridge.f_hz - on_ridge))
        aid = Aiding(t, curves[a.sat_row] + offset, f"ridge {ridge.ridge_id} ({a.name})")
        try:
            aid.check_covers(duration, res.info.sample_rate_hz)
        except UserInputError as exc:
            skipped.append(str(exc))
            continue
        out.append((ridge, a, aid))
    return out


def track_result(res, cfg: CarrierConfig | None = None, chunk_samples: int = 1 << 20,
                 progress: Callable[[int], None] | None = None,
                 skipped: list | None = None) -> list[tuple[object, object, CarrierTrack]]:
    """Track the carrier of every associated tone of a pipeline result: (ridge, association,
    track); tones left out are described in `skipped`."""
    aid = aidings(res, skipped=skipped)
    if not aid:
        return []
    info = res.info

    def blocks():
        for b in capture_io.iter_chunks(info, chunk_samples):
            yield b
            if progress:
                progress(b.size)

    tracks = track_tones(blocks(), info.sample_rate_hz, [x[2] for x in aid], info.duration_s, cfg)
    return [(r, a, tr) for (r, a, _), tr in zip(aid, tracks)]


def _iso(start: _dt.datetime | None, t: float) -> str:
    if start is None:
        return ""
    return (start + _dt.timedelta(seconds=float(t))).isoformat().replace("+00:00", "Z")


def _num(v: float):
    return "" if not math.isfinite(v) else float(v)


def write_carrier_csv(res, tracked: list, out_dir: Path) -> dict[str, Path]:
    """carrier_phase.csv (+ .columns.txt); rows sorted by epoch, then ridge."""
    from leonav_runtime.common.output import write_csv

    out_dir = Path(out_dir)
    shift = res.info.rf_center_hz - res.f_c_hz
    rows = []
    for ridge, a, tr in tracked:
        tone = "" if a.tone_index is None else a.tone_index
        for k in range(tr.t_s.size):
            rows.append([float(tr.t_s[k]), _iso(res.info.start_utc, tr.t_s[k]), a.norad_id, a.name, ridge.ridge_id,
                         tone, _num(tr.phase_cycles[k]), _num(tr.sigma_cycles[k]), int(tr.locked[k]),
                         int(tr.slip[k]), int(tr.arc[k]), _num(tr.cn0_dbhz[k]), _num(tr.freq_hz[k] + shift),
                         _num(tr.rate_hz_s[k])])
    rows.sort(key=lambda r: (r[0], r[4]))
    path = write_csv(out_dir / "carrier_phase.csv", [c[0] for c in CARRIER_COLUMNS], rows)
    cols = out_dir / "carrier_phase.columns.txt"
    cols.write_text("".join(f"{n} [{u}]: {d}\n" for n, u, d in CARRIER_COLUMNS))
    return {"carrier": path, "carrier_columns": cols}


def summary_line(tracked: list, skipped: list | None = None) -> str:
    """One line for the command's output (and one per tone left out)."""
    notes = "".join(f"\ncarrier: left out: {s}" for s in (skipped or []))
    if not tracked:
        return "carrier: no associated tone to track" + notes
    ep = sum(tr.t_s.size for _, _, tr in tracked)
    lk = sum(int(tr.locked.sum()) for _, _, tr in tracked)
    slips = sum(int(tr.slip.sum()) for _, _, tr in tracked)
    return (f"carrier: {len(tracked)} tone(s) tracked, locked on {lk} of {ep} epochs "
            f"({100 * lk / max(ep, 1):.1f} %), {slips} slip(s) or relock(s)") + notes
