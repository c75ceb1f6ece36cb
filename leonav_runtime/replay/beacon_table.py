"""The session's beacon capture -> Doppler-rate measurements -> `inputs.DopplerRateTable`.

`beacon_measurements` runs `beacons.pipeline.process_capture` on sdr.cu8 with the capture
start from its monotonic stamp through the time map (SigMF core:datetime is the host
clock); each associated ridge epoch becomes one measurement (t s on the replay axis, NORAD
id, row in the element set, Doppler-rate z Hz/s and its fit sigma Hz/s). The carrier f_c
(of the pipeline's predictions and of the filter's model) is the capture's RF centre
(SigMF leonav:rf_center_hz = core:frequency + leonav:lnb_lo_hz: the recorder tunes the
beacon to baseband 0); without a readable Ku-band value, `STARLINK_BEACON_HZ` with a note.

`doppler_rate_table` adds each satellite's SGP4 ECEF state and acceleration at the
measurement times and floors the sigma (`ReplayOptions.doppler_rate_sigma_floor_hz_s`); with
operator ephemerides (`--operator-ephemerides`, docs/ephemerides.md) a satellite whose file
covers its measurement times takes its states from the file instead.

Carrier phase (a mode with the `phase` word): `beacon_measurements(..., track_phase=True)` also
runs the carrier tracker (`carrier_hook.track_result`) on the processed capture and turns
its epochs into time differences (`inputs.carrier_phase.phase_differences`, breaks counted);
`carrier_phase_table` adds the satellite's state at t and its position at t - interval (the
same propagation as the Doppler-rate table) and refers each tone to the channel centre
(`inputs.carrier_phase.tone_to_centre`: tone index x the comb spacing of the association).
A tone whose comb index is unknown (offset known only modulo the spacing) is left out, its
epochs counted.
"""
from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import math
import warnings
from pathlib import Path

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gen.constants import KU_DOWNLINK_MAX_HZ, KU_DOWNLINK_MIN_HZ, STARLINK_BEACON_HZ
from leonav_runtime.inputs import SAT_A_MPS2, SAT_R_M, SAT_V_MPS, CarrierPhaseTable, DopplerRateTable
from leonav_runtime.inputs.carrier_phase import PhaseDifferences, phase_differences, tone_to_centre
from leonav_runtime.replay.timebase import utc_of

KU_DOWNLINK_HZ = (KU_DOWNLINK_MIN_HZ, KU_DOWNLINK_MAX_HZ)  # a capture RF centre outside is not a beacon carrier


@dataclasses.dataclass
class BeaconMeasurements:
    """Doppler-rate measurements of the capture: t (n,) s on the replay axis, norad_id (n,),
    sat_index (n,) row in the element set, z_hz_s (n,), sigma_hz_s (n,) the fit's 1-sigma."""

    t: np.ndarray
    norad_id: np.ndarray
    sat_index: np.ndarray
    z_hz_s: np.ndarray
    sigma_hz_s: np.ndarray
    phase: "PhaseMeasurements | None" = None    # the tracked carrier phase, when asked for

    @classmethod
    def empty(cls) -> "BeaconMeasurements":
        z = np.zeros(0)
        return cls(z, z.astype(int), z.astype(int), z, z)


@dataclasses.dataclass
class PhaseMeasurements:
    """Carrier-phase time differences of the capture's tones, before satellite states: diffs
    (t s on the replay axis, raw tone phase z, not yet referred to the centre), sat_index (n,)
    row in the element set, tone_offset_hz (n,) the tone minus the channel centre (Hz), and
    counts (tones tracked and left out, epochs of tones without a comb index, differences,
    breaks by reason)."""

    diffs: PhaseDifferences
    sat_index: np.ndarray
    tone_offset_hz: np.ndarray
    counts: dict

    @classmethod
    def empty(cls, reason: str) -> "PhaseMeasurements":
        z = np.zeros(0)
        counts = {"tones_tracked": 0, "differences": 0, "reason_empty": reason}
        return cls(PhaseDifferences(z, z, z.astype(int), z.astype(int), z, z, {}), z.astype(int), z, counts)


def phase_measurements(res, t0: float, spacing_hz: float, cfg=None, progress=None) -> PhaseMeasurements:
    """Track the carrier of the associated tones of pipeline result `res` and difference it
    (module doc); t0 (s): the capture's first sample on the replay axis."""
    from leonav_runtime.beacons.carrier import CarrierConfig
    from leonav_runtime.beacons.carrier_hook import track_result

    cfg = cfg or CarrierConfig()
    skipped: list[str] = []
    tracked = track_result(res, cfg, progress=progress, skipped=skipped)
    cols: dict[str, list] = {k: [] for k in ("t", "sat", "tone", "phi", "sig", "lk", "arc")}
    offset_of, index_of = {}, {}
    no_index_tones = no_index_epochs = 0
    for ridge, a, tr in tracked:
        if a.tone_index is None:          # offset known modulo the spacing only: T df unknown
            no_index_tones += 1
            no_index_epochs += int(tr.t_s.size)
            continue
        offset_of[ridge.ridge_id] = a.tone_index * spacing_hz
        index_of[ridge.ridge_id] = int(res.predictions.sat_index[a.sat_row])
        n = tr.t_s.size
        for key, v in (("t", t0 + tr.t_s), ("sat", np.full(n, a.norad_id)), ("tone", np.full(n, ridge.ridge_id)),
                       ("phi", tr.phase_cycles), ("sig", tr.sigma_cycles), ("lk", tr.locked), ("arc", tr.arc)):
            cols[key].append(np.asarray(v))
    cat = {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in cols.items()}
    diffs = phase_differences(cat["t"], cat["sat"], cat["tone"], cat["phi"], cat["sig"], cat["lk"], cat["arc"],
                              cfg.epoch_s)
    counts = {"tones_tracked": len(tracked), "tones_left_out": len(skipped), "left_out": skipped,
              "tones_without_comb_index": no_index_tones, "epochs_without_comb_index": no_index_epochs,
              "epochs": diffs.counts["epochs"], "pairs": diffs.counts["pairs"],
              "differences": diffs.counts["differences"], "breaks": diffs.counts["breaks"],
              "epoch_s": cfg.epoch_s}
    sat_index = np.array([index_of[int(r)] for r in diffs.tone_id], int)
    offsets = np.array([offset_of[int(r)] for r in diffs.tone_id], float)
    return PhaseMeasurements(diffs, sat_index, offsets, counts)


def _sigmf_mono_start(folder: Path) -> float | None:
    meta = folder / "sdr.sigmf-meta"
    if not meta.is_file():
        return None
    try:
        glob = json.loads(meta.read_text()).get("global", {})
    except json.JSONDecodeError:
        return None          # open_capture reports the bad metadata with its line
    v = glob.get("leonav:t_mono_start_s")
    return float(v) if isinstance(v, (int, float)) else None


def capture_carrier(info) -> tuple[float, str]:
    """Beacon carrier f_c (Hz) of a capture and where it came from.

    `leonav record` tunes the beacon to baseband 0, so f_c is the capture's RF centre
    (`CaptureInfo.rf_center_hz`: SigMF leonav:rf_center_hz = core:frequency +
    leonav:lnb_lo_hz). A value outside the Ku downlink band (`KU_DOWNLINK_HZ`, e.g. a
    capture without an LNB LO) falls back to `STARLINK_BEACON_HZ`."""
    rf = float(info.rf_center_hz)
    if math.isfinite(rf) and KU_DOWNLINK_HZ[0] <= rf <= KU_DOWNLINK_HZ[1]:
        return rf, f"capture metadata ({info.source or info.path}: RF centre = tuned frequency + LNB LO)"
    return STARLINK_BEACON_HZ, (f"default {STARLINK_BEACON_HZ / 1e9:g} GHz: the capture's RF centre "
                                f"{rf / 1e9:.6g} GHz (tuned {info.center_freq_hz / 1e9:.6g} GHz + LNB LO "
                                f"{info.lnb_lo_hz / 1e9:.6g} GHz) is outside the Ku downlink band "
                                f"{KU_DOWNLINK_HZ[0] / 1e9:g}-{KU_DOWNLINK_HZ[1] / 1e9:g} GHz")


def default_carrier(reason: str) -> dict:
    return {"f_c_hz": STARLINK_BEACON_HZ, "f_c_source": f"default {STARLINK_BEACON_HZ / 1e9:g} GHz: {reason}"}


def default_elements(start_utc: _dt.datetime, notes: list[str]):
    """The built-in Walker Starlink set of synthetic sessions (`session_synth.builtin_starlink`)."""
    from leonav_runtime.simulation.session_synth import builtin_starlink

    notes.append("beacons: no --tle given: built-in Walker Starlink constellation at the UTC minute nearest the "
                 "capture start (right for synthetic sessions only; give real element sets for a real capture)")
    return builtin_starlink(start_utc)


def beacon_measurements(folder: Path, out_dir: Path | None, to_utc, time_source_ok: bool, epoch: float, origin,
                        elements, notes: list[str], progress=None,
                        track_phase: bool = False) -> tuple[BeaconMeasurements, dict, object]:
    """Run the beacon pipeline on the session's capture; returns (measurements, summary, elements).

    summary["f_c_hz"], ["f_c_source"]: the carrier f_c (`capture_carrier`, else the default).
    track_phase: also track the tones' carrier phase (measurements.phase, summary["carrier_phase"])."""
    from leonav_runtime.beacons import capture_io, pipeline
    from leonav_runtime.beacons.predict import Site

    data = folder / "sdr.cu8"
    if not data.exists():
        return BeaconMeasurements.empty(), {"reason_empty": "no sdr.cu8 in the session"} | default_carrier(
            "no capture in the session"), elements
    try:
        info = capture_io.open_capture(data)
    except UserInputError as exc:
        return BeaconMeasurements.empty(), {"reason_empty": str(exc)} | default_carrier(
            f"capture metadata unreadable ({exc})"), elements
    f_c_hz, f_c_src = capture_carrier(info)
    carrier = {"f_c_hz": f_c_hz, "f_c_source": f_c_src}
    mono = _sigmf_mono_start(folder)
    if mono is not None and time_source_ok:
        info.start_utc = utc_of(float(to_utc(mono)))
        start_src = "leonav:t_mono_start_s through the GNSS time map"
    else:
        start_src = "SigMF core:datetime (host wall clock)"
        notes.append("beacons: capture start from the host wall clock (no monotonic stamp or no GNSS time map)")
    if info.start_utc is None:
        return BeaconMeasurements.empty(), {"reason_empty": f"{data}: capture start time unknown"} | carrier, elements
    if elements is None:
        elements = default_elements(info.start_utc, notes)
    site = Site(*origin)
    cfg = pipeline.PipelineConfig(f_c_hz=f_c_hz, band_hz=min(1.2e6, info.sample_rate_hz))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = pipeline.process_capture(info, elements, site, cfg, progress)
    for w in {str(w.message) for w in caught}:
        notes.append(f"beacons: {w}")
    if out_dir is not None:
        pipeline.write_outputs(res, out_dir / "beacons")
    summ = pipeline.summary(res)
    summary = {"capture_start_utc": info.start_utc, "capture_start_source": start_src,
               "counts": summ["counts"], "rate_residual_abs_hz_s": summ["rate_residual_abs_hz_s"],
               "reason_empty": summ["reason_empty"], **carrier,
               "associations": [{k: a[k] for k in ("ridge_id", "status", "norad_id", "name", "reason")}
                                for a in summ["associations"]]}
    t0 = info.start_utc.timestamp() - epoch
    rows = []
    for ridge, m, a in zip(res.ridges, res.measurements, res.associations):
        if a.status != "associated" or m.t_s.size == 0:
            continue
        idx = int(res.predictions.sat_index[a.sat_row])
        for k in range(m.t_s.size):
            rows.append((t0 + m.t_s[k], a.norad_id, idx, m.rate_hz_s[k], m.sigma_rate_hz_s[k]))
    rows.sort()
    phase = None
    if track_phase:
        phase = phase_measurements(res, t0, cfg.association.comb.spacing_hz)
        summary["carrier_phase"] = phase.counts
    if not rows:
        out = BeaconMeasurements.empty()
    else:
        arr = list(zip(*rows))
        out = BeaconMeasurements(np.array(arr[0]), np.array(arr[1], int), np.array(arr[2], int), np.array(arr[3]),
                                 np.array(arr[4]))
    out.phase = phase
    return out, summary, elements


def doppler_rate_table(meas: BeaconMeasurements, elements, epoch_utc: _dt.datetime,
                       sigma_floor_hz_s: float, operator=None, notes: list[str] | None = None,
                       stats: dict | None = None) -> DopplerRateTable:
    """The measurements with each satellite's SGP4 ECEF state and acceleration at their times
    (t s since `epoch_utc`) and 1-sigma max(fit sigma, floor) (Hz/s). operator: an
    `OperatorEphemerisSet`; a satellite it covers at all its times takes its states from it
    (how many did goes to `notes`; with `stats`, the measurements of each kind are added to its
    `states_from_operator_files` and `states_from_element_sets`)."""
    from leonav_runtime.orbits import propagate_ecef

    sat = np.zeros((meas.t.size, 9))
    from_files = 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")     # staleness is reported by the beacon step
        for idx in np.unique(meas.sat_index):
            sel = meas.sat_index == idx
            one = elements.select([int(idx)])
            if operator is not None:
                from leonav_runtime.orbits.operator_states import operator_sat_states
                st, used = operator_sat_states(operator, one, epoch_utc, meas.t[sel])
                from_files += int(used[0])
                if stats is not None:
                    key = "states_from_operator_files" if used[0] else "states_from_element_sets"
                    stats[key] = stats.get(key, 0) + int(sel.sum())
            else:
                st = propagate_ecef(one, epoch_utc, meas.t[sel])
            sat[sel, SAT_R_M], sat[sel, SAT_V_MPS], sat[sel, SAT_A_MPS2] = (st.r_ecef_m[0], st.v_ecef_mps[0],
                                                                           st.a_ecef_mps2[0])
    if operator is not None and notes is not None:
        n_sat = int(np.unique(meas.sat_index).size)
        notes.append(f"beacons: {from_files} of {n_sat} satellites' states from operator ephemerides, "
                     f"{n_sat - from_files} from their element sets (no file, or not over their measurement times)")
    return DopplerRateTable(meas.t, meas.norad_id, meas.z_hz_s, np.maximum(meas.sigma_hz_s, sigma_floor_hz_s), sat)


def _states(elements, idx: int, epoch_utc: _dt.datetime, t: np.ndarray, operator):
    """States (r, v, a ECEF) of element-set row idx at t (s since epoch_utc), and whether the
    operator's file gave them (the Doppler-rate table's rule)."""
    from leonav_runtime.orbits import propagate_ecef

    one = elements.select([int(idx)])
    if operator is not None:
        from leonav_runtime.orbits.operator_states import operator_sat_states
        st, used = operator_sat_states(operator, one, epoch_utc, t)
        return st, bool(used[0])
    return propagate_ecef(one, epoch_utc, t), False


def carrier_phase_table(pm: PhaseMeasurements, elements, epoch_utc: _dt.datetime, origin_ecef_m,
                        operator=None, notes: list[str] | None = None, stats: dict | None = None) -> CarrierPhaseTable:
    """The phase differences with each satellite's ECEF state at t and position at
    t - interval (SGP4, or the operator's file where it covers both: `doppler_rate_table`'s
    propagation), each tone referred to the channel centre with the range change predicted
    for a receiver at origin_ecef_m (3,) m (`inputs.carrier_phase.tone_to_centre`)."""
    d = pm.diffs
    n = d.t.size
    sat = np.zeros((n, 9))
    prev = np.zeros((n, 3))
    from_files = 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")     # staleness is reported by the beacon step
        for idx in np.unique(pm.sat_index):
            sel = pm.sat_index == idx
            both = np.concatenate([d.t[sel], d.t_prev[sel]])
            st, used = _states(elements, int(idx), epoch_utc, both, operator)
            from_files += int(used)
            if stats is not None and operator is not None:   # as doppler_rate_table's, per measurement
                key = "states_from_operator_files" if used else "states_from_element_sets"
                stats[key] = stats.get(key, 0) + int(sel.sum())
            m = int(sel.sum())
            sat[sel, SAT_R_M], sat[sel, SAT_V_MPS], sat[sel, SAT_A_MPS2] = (st.r_ecef_m[0][:m], st.v_ecef_mps[0][:m],
                                                                           st.a_ecef_mps2[0][:m])
            prev[sel] = st.r_ecef_m[0][m:]
    if operator is not None and notes is not None:
        n_sat = int(np.unique(pm.sat_index).size)
        notes.append(f"beacons: carrier phase: {from_files} of {n_sat} satellites' states from operator "
                     f"ephemerides, {n_sat - from_files} from their element sets")
    r0 = np.asarray(origin_ecef_m, float)
    drho = np.linalg.norm(sat[:, SAT_R_M] - r0, axis=1) - np.linalg.norm(prev - r0, axis=1)
    z = tone_to_centre(d.z_cycles, d.interval_s, pm.tone_offset_hz, drho)
    return CarrierPhaseTable(d.t, d.norad_id, z, d.sigma_cycles, sat, None, d.interval_s, prev, pm.tone_offset_hz)
