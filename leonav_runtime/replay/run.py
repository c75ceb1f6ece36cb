"""A recorded session through the filter: session -> tables -> `inputs.assemble` -> modes -> scores.

`decode_inputs` (steps 1-6 of the package doc) builds the tables of one session and hands
them to the road into the filter; `replay_session` runs every mode on the same inputs,
scores them (`scoring.py`) and writes the outputs (`report.py`).
"""
from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path

import numpy as np

from leonav_runtime.core import filter as lfilter
from leonav_runtime.core import navfuncs, orbit_states
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.inputs import DopplerRateTable, FilterInputs, FirstFixPrior, FixTable, assemble, filter_params
from leonav_runtime.replay.beacon_table import (BeaconMeasurements, beacon_measurements, carrier_phase_table,
                                                default_carrier, doppler_rate_table)
from leonav_runtime.replay.gnss_raw import RawGnss, raw_gnss
from leonav_runtime.replay.gnss_table import fix_height_m, fix_table, usable_fix
from leonav_runtime.replay.options import (LATENCY_PRIOR_SIGMA_S, ReplayOptions, canonical_modes, check_options,
                                           latency_estimate, latency_given_s, latency_values, replay_mode,
                                           uses_carrier_phase, uses_raw_gnss)
from leonav_runtime.replay.timebase import device_baud, filter_profile, imu_table, mono_to_utc_function, utc_of

WITMOTION_ATTITUDE = "WitMotion angle output"
RMC_VELOCITY = "initializing fix's RMC speed/course (NAV-PVT velocity)"
ORBIT_SLOTS = 64   # --orbit-states: satellites whose offsets are states at once (a capture holds a few)


@dataclasses.dataclass
class SessionInputs(FilterInputs):
    """`FilterInputs` of a session plus the replay's extras: the beacon step's summary and
    measurements (before satellite states), and the modes that cannot run, with reasons."""

    beacons: dict = dataclasses.field(default_factory=dict)
    raw_gnss: dict = dataclasses.field(default_factory=dict)      # the RXM-RAWX single-point pass (counts)
    beacon_measurements: BeaconMeasurements = dataclasses.field(default_factory=BeaconMeasurements.empty)
    skipped: dict[str, str] = dataclasses.field(default_factory=dict)   # mode -> reason

    @classmethod
    def of(cls, inputs: FilterInputs, **extra) -> "SessionInputs":
        return cls(**{f.name: getattr(inputs, f.name) for f in dataclasses.fields(FilterInputs)}, **extra)

    @property
    def doppler_rate(self) -> DopplerRateTable:
        """The Doppler-rate table as used (inside the IMU span)."""
        return self.satellites.get("doppler_rate") or DopplerRateTable.empty()


def replay_prior(options: ReplayOptions, profile) -> FirstFixPrior:
    """The replay's start rule: the first usable fix, the WitMotion angles, `--yaw-deg`."""
    return FirstFixPrior(profile, yaw_rad=None if options.yaw_deg is None else math.radians(options.yaw_deg),
                         attitude_source=WITMOTION_ATTITUDE, yaw_given_source="--yaw-deg",
                         velocity_source=RMC_VELOCITY,
                         fix_latency_sigma_s=LATENCY_PRIOR_SIGMA_S if options.gnss_latency_s == "estimate" else 0.0)


def session_inputs(epoch_utc, origin, imu, fixes: FixTable, meas: BeaconMeasurements, elements, options,
                   profile, nav: navfuncs.NavFunctions, notes: list[str], f_c_hz: float,
                   spp=None) -> SessionInputs:
    """The road into the filter for one session's tables (also used by the direct simulation);
    spp: the single-point pass of the session's RXM-RAWX (pseudorange modes), or None."""
    operator = None
    phase = meas.phase
    measured = np.unique(np.concatenate([meas.sat_index, phase.sat_index if phase is not None else []]).astype(int))
    if options.operator_ephemerides and measured.size:
        from leonav_runtime.orbits.operator_ephemeris import load_folder

        # only the files of the satellites measured (a full folder holds ~10,000)
        wanted = sorted({str(elements.names[int(i)]).strip() for i in measured})
        operator = load_folder(options.operator_ephemerides, names=wanted)
    doppler_rate = doppler_rate_table(meas, elements, epoch_utc, options.doppler_rate_sigma_floor_hz_s, operator, notes)
    satellites = [doppler_rate]
    if phase is not None:
        from leonav_runtime.orbits.geometry import geodetic_to_ecef

        satellites.append(carrier_phase_table(phase, elements, epoch_utc, geodetic_to_ecef(*origin), operator, notes))
        c = phase.counts
        notes.append(carrier_phase_note(c))
    gnss = None
    if spp is not None:
        from leonav_runtime.gnss.coupled import observation_table

        gnss = observation_table(spp, epoch_utc)
    orbit_consider = provider = None
    if operator is not None and options.orbit_states_sigma_m is not None:
        notes.append("beacons: the operator covariance is not added to R: --orbit-states estimates each "
                     "satellite's orbit offset from the operator states instead")
    elif operator is not None:    # the files' covariance into every beacon observable's R (consider term)
        from leonav_runtime.inputs.consider import OrbitConsider
        from leonav_runtime.orbits.operator_consider import OperatorCovariance, names_by_id

        provider = OperatorCovariance(operator, epoch_utc, names_by_id(elements.norad_ids, elements.names))
        orbit_consider = OrbitConsider({}, covariance={table.KIND: provider for table in satellites})
    corrections = recorded_corrections(options, epoch_utc)
    inputs = assemble(imu, filter_params(origin, profile, f_c_hz, latency_values(options.gnss_latency_s)),
                      replay_prior(options, profile),
                      fixes=fixes, satellites=satellites, nav=nav, notes=notes, epoch_utc=epoch_utc,
                      origin=origin, gnss=gnss, orbit_consider=orbit_consider, corrections=corrections)
    if corrections is not None:
        d = corrections.describe()
        inputs.counts["corrections"] = d
        inputs.notes.append(f"corrections: {d['counts'].get('doppler_rate_applied', 0)} Doppler-rate records "
                            f"corrected, {d['counts'].get('doppler_rate_stale', 0)} stale, "
                            f"{d['counts'].get('doppler_rate_none', 0)} without; "
                            f"{sum(v for k, v in d['counts'].items() if k.startswith('rejected_'))} lines refused")
    if provider is not None:
        kinds = " and ".join(table.KIND.replace("_", "-") for table in satellites)
        inputs.notes.append(f"beacons: {kinds} R + J P J^T of the operator covariance; "
                            f"{provider.uncovered_records} records without it")
    out = SessionInputs.of(inputs, beacon_measurements=meas)
    out.counts["doppler_rate_satellites"] = int(np.unique(out.doppler_rate.sat_id).size)
    if phase is not None:
        out.counts["carrier_phase"] = phase.counts
    return out


def carrier_phase_note(c: dict) -> str:
    """One line of the tracker's counts: tones, differences and breaks by reason."""
    if c.get("reason_empty"):
        return f"carrier phase: no tone tracked ({c['reason_empty']})"
    b = c["breaks"]
    return (f"carrier phase: {c['tones_tracked']} tone(s) tracked ({c['tones_left_out']} left out, "
            f"{c['tones_without_comb_index']} without a comb index: {c['epochs_without_comb_index']} epochs "
            f"unused), {c['differences']} differences of {c['pairs']} epoch pairs; breaks: "
            + ", ".join(f"{k} {v}" for k, v in b.items()))


def recorded_corrections(options: ReplayOptions, epoch_utc):
    """The store of `--corrections FILE` (a base's recorded lines), or None."""
    if not options.corrections:
        return None
    from leonav_runtime.base.client import feed_lines
    from leonav_runtime.inputs.corrections import DEFAULT_MAX_AGE_S, DifferentialCorrections

    try:
        data = Path(options.corrections).read_bytes()
    except OSError as exc:
        raise UserInputError(f"--corrections {options.corrections}: {exc.strerror or exc}") from None
    store = DifferentialCorrections(options.corrections_max_age_s or DEFAULT_MAX_AGE_S,
                                    epoch_unix=epoch_utc.timestamp())
    feed_lines(store, data.split(b"\n"))
    return store


def decode_inputs(folder: Path, options: ReplayOptions, elements=None, out_dir: Path | None = None,
                  nav: navfuncs.NavFunctions | None = None, progress=None) -> SessionInputs:
    """Decode a session folder into SessionInputs (package doc, steps 1-6)."""
    from leonav.hardware import session as hw_session

    _, mode_notes = canonical_modes(options.modes)
    options = check_options(options)
    nav = nav or navfuncs.NavFunctions()
    folder = Path(folder)
    dec = hw_session.decode_session(folder)
    notes: list[str] = list(mode_notes)
    if not (folder / "imu.raw").exists():
        raise UserInputError(f"{folder}: no imu.raw: every replay mode propagates with the IMU")
    if not dec.imu_samples:
        raise UserInputError(f"{folder / 'imu.raw'}: no complete WitMotion cycle decoded "
                             f"(rejected: {dec.imu_summary.get('rejected')})")
    if dec.imu_samples[0].t_mono_s == dec.imu_samples[-1].t_mono_s:
        raise UserInputError(f"{folder / 'imu.chunks.csv'}: the {len(dec.imu_samples)} WitMotion cycles all arrived "
                             f"at t_mono_s {dec.imu_samples[0].t_mono_s!r}: the stamps do not advance, so the "
                             "samples cannot be placed in time")
    raw = RawGnss(None, {}, "")
    if any(uses_raw_gnss(m) for m in options.modes):
        raw = raw_gnss(dec.gnss_records, options, nav, str(folder / "gnss.raw"))
    to_utc, time_src = mono_to_utc_function(dec, latency_given_s(options.gnss_latency_s))
    if not dec.time_map.valid:
        notes.append(f"time: {time_src}")
    imu, epoch, counts = imu_table(dec.imu_samples, to_utc, notes, device_baud(dec, "imu"))
    epoch_utc = utc_of(epoch)
    from leonav.hardware.records import GnssFix

    any_fix = any(isinstance(r, GnssFix) for r in dec.gnss_records)
    first_fix = next((r for r in dec.gnss_records if isinstance(r, GnssFix) and usable_fix(r)), None)
    if options.origin_deg is not None:
        lat, lon, h = options.origin_deg
        origin = (math.radians(lat), math.radians(lon), float(h))
        origin_src = "--origin"
    elif first_fix is not None:
        origin = (first_fix.lat_rad, first_fix.lon_rad, fix_height_m(first_fix))
        origin_src = "first GNSS fix with a finite latitude, longitude and height"
    elif raw.spp is not None:
        from leonav_runtime.gnss.coupled import first_solution_origin

        origin = first_solution_origin(raw.spp)
        origin_src = "first single-point solution of the RXM-RAWX pseudoranges"
    else:
        origin = None
        origin_src = "none"
    fixes, fcounts = fix_table(dec.gnss_records, to_utc, epoch, origin, notes) if origin else (FixTable.empty(),
                                                                                               {"gnss_fixes": 0})
    if fixes.t.size == 0 and raw.spp is not None:
        from leonav_runtime.gnss.coupled import spp_fixes

        fixes = spp_fixes(raw.spp, epoch_utc, origin)
        fcounts["fix_source"] = "single-point solutions of RXM-RAWX"
        notes.append("GNSS: no position fix in gnss.raw: the single-point solutions of the RXM-RAWX pseudoranges "
                     f"are the fixes ({fixes.t.size}; they start the filter and are the fix modes' measurements)")
    meas, bsum, elements = (beacon_measurements(folder, out_dir, to_utc, dec.time_map.valid, epoch, origin, elements,
                                                notes, progress, track_phase=uses_carrier_phase(options.modes))
                            if origin else
                            (BeaconMeasurements.empty(), {"reason_empty": "no position to predict satellites from "
                                                          "(no GNSS fix; give --origin)"}
                             | default_carrier("no beacon processing"), elements))
    if bsum["f_c_source"].startswith("default") and (folder / "sdr.cu8").exists():
        notes.append(f"beacons: carrier f_c = {bsum['f_c_source']}")
    profile = filter_profile(counts["imu_period_s"], quantized=True)
    if origin is None:
        # nothing can run: keep a valid (empty) result with the reasons
        origin = (0.0, 0.0, 0.0)
    inputs = session_inputs(epoch_utc, origin, imu, fixes, meas, elements, options, profile, nav, notes,
                            bsum["f_c_hz"], raw.spp)
    inputs.counts |= counts | fcounts | {"gnss_decoder": dec.gnss_summary, "imu_decoder": dec.imu_summary}
    inputs.beacons, inputs.raw_gnss = bsum, raw.summary
    inputs.init |= {"origin": origin_src, "origin_deg": [math.degrees(origin[0]), math.degrees(origin[1]), origin[2]],
                    "time_axis": time_src, "epoch_utc": epoch_utc}
    if origin_src == "--origin":
        inputs.init["origin_given"] = True
    for mode in options.modes:
        if uses_raw_gnss(mode) and raw.reason:
            inputs.skipped[mode] = raw.reason
        elif uses_raw_gnss(mode) and not dec.time_map.valid:
            # pseudoranges are on GPS time; an IMU axis on the host clock can be seconds off it
            inputs.skipped[mode] = ("no GNSS time tag in gnss.raw: the IMU is on the host clock, which can be "
                                    "seconds off the pseudoranges' GPS time")
        elif "fix" in replay_mode(mode).streams and fixes.t.size == 0:
            inputs.skipped[mode] = ("no GNSS fix in gnss.raw" if not any_fix else
                                    "no GNSS fix with a finite latitude, longitude and height in gnss.raw"
                                    if first_fix is None else "no GNSS fix inside the IMU time span")
        elif origin_src == "none":
            inputs.skipped[mode] = "no initial position: no GNSS fix (give --origin LAT LON H)"
    for mode, reason in skip_reasons(inputs, options.modes).items():
        inputs.skipped.setdefault(mode, reason)
    return inputs


def check_truth_csv(path: Path) -> None:
    """truth.csv as `scoring.truth_reference` reads it: UTF-8, a header with every truth column,
    then rows with a finite number in each of them, in time order (UserInputError naming the
    file and line; a cut last row says the file is truncated)."""
    from leonav_runtime.replay.scoring import TRUTH_COLUMNS

    try:
        lines = path.read_bytes().decode("utf-8").splitlines()
    except UnicodeDecodeError as exc:
        raise UserInputError(f"{path}: not UTF-8 text (byte {exc.start}); expected a CSV") from None
    header = lines[0].split(",") if lines else []
    missing = [c for c in TRUTH_COLUMNS if c not in header]
    if missing or len(lines) < 2:
        raise UserInputError(f"{path}: expected a header with {', '.join(TRUTH_COLUMNS)} and at least one row"
                             + (f" (missing {', '.join(missing)})" if missing else ""))
    cols, t_prev = [header.index(c) for c in TRUTH_COLUMNS], -math.inf
    for line_no, line in enumerate(lines[1:], start=2):
        cells = line.split(",")
        if len(cells) != len(header):
            cut = " (the file is cut short)" if line_no == len(lines) else ""
            raise UserInputError(f"{path}:{line_no}: {len(cells)} of {len(header)} fields{cut}")
        try:
            values = [float(cells[j]) for j in cols]
        except ValueError:
            values = [math.nan]
        if not all(math.isfinite(v) for v in values) or values[0] <= t_prev:
            raise UserInputError(f"{path}:{line_no}: expected finite numbers in {', '.join(TRUTH_COLUMNS)} with "
                                 f"{TRUTH_COLUMNS[0]} increasing, got {line[:80]!r}")
        t_prev = values[0]


def skip_reasons(inputs: SessionInputs, modes) -> dict[str, str]:
    """Modes that cannot run on these inputs, with the reason."""
    out = {}
    for mode in modes:
        if "fix" in replay_mode(mode).streams and inputs.records["fix"].size == 0:
            out[mode] = "no GNSS fix inside the IMU time span"
        elif "gnss_pseudorange" in replay_mode(mode).streams and np.size(inputs.records.get("gnss_pseudorange", ())) == 0:
            out[mode] = "no RXM-RAWX pseudorange inside the IMU time span"
        elif "doppler_rate" in replay_mode(mode).streams and inputs.records["doppler_rate"].size == 0:
            out[mode] = "no associated Doppler-rate measurement: " + str(
                inputs.beacons.get("reason_empty") or "no ridge was associated with a satellite")
        elif "carrier_phase" in replay_mode(mode).streams and np.size(inputs.records.get("carrier_phase", ())) == 0:
            out[mode] = "no carrier-phase difference inside the IMU time span: " + str(
                inputs.beacons.get("reason_empty") or "no associated tone held lock over two epochs with a "
                "known comb index")
    return out


def run_modes(inputs: FilterInputs, modes, gate_nis: float, nav: navfuncs.NavFunctions,
              skipped: dict | None = None, orbit_sigma_m=None) -> dict:
    """{mode: (records, RunResult, seconds)} for every mode not skipped (default: inputs.skipped);
    orbit_sigma_m (radial, along, cross; m): the Starlink modes estimate each satellite's orbit
    offsets as states with this prior (ephemeris method 1; `RunResult.orbit_states`)."""
    skipped = getattr(inputs, "skipped", {}) if skipped is None else skipped
    out = {}
    for mode in modes:
        if mode in skipped:
            continue
        recs = inputs.merged(replay_mode(mode).streams)
        ekf = lfilter.EKF(inputs.x0, inputs.P0, inputs.params, gate=gate_nis or None, library=nav.library)
        orbit = None
        if orbit_sigma_m is not None and np.isin(recs["kind"], sorted(orbit_states.offset_kinds())).any():
            orbit = orbit_states.OrbitStates(nav.layout.NDX, len(nav.library.meas_ids), ORBIT_SLOTS, orbit_sigma_m)
        t0 = time.perf_counter()
        res = ekf.run(recs, orbit=orbit)
        out[mode] = (recs, res, time.perf_counter() - t0)
    return out


def replay_session(folder: str | Path, out_dir: str | Path, options: ReplayOptions | None = None, elements=None,
                   progress=None, nav: navfuncs.NavFunctions | None = None,
                   inputs: SessionInputs | None = None) -> dict:
    """Decode, run the modes, score against truth.csv or the fixes, write the outputs; returns metrics.

    inputs: the session already decoded by `decode_inputs` with the same options and
    out_dir (its beacon outputs are there), so a caller that needs them decodes only once."""
    from leonav_runtime.replay import report, scoring

    given = options or ReplayOptions()
    options = check_options(given)
    folder, out_dir = Path(folder), Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    nav = nav or navfuncs.NavFunctions()
    if inputs is None:
        inputs = decode_inputs(folder, given, elements, out_dir, nav, progress)
    nav.params = inputs.params
    runs = run_modes(inputs, options.modes, options.gate_nis, nav, orbit_sigma_m=options.orbit_states_sigma_m)
    truth = folder / "truth.csv"
    ref = None
    if options.use_truth and truth.is_file():
        check_truth_csv(truth)
        ref = scoring.truth_reference(truth, inputs.epoch_utc, inputs.origin, nav)
    elif inputs.fixes.t.size:
        ref = scoring.fix_reference(inputs.fixes)
        inputs.notes.append("reference = the GNSS fixes: fix+imu is compared with its own input (optimistic); "
                            "velocity and attitude have no reference")
    scored = scoring.evaluate(inputs, runs, ref, nav)
    metrics = {
        "session": str(folder), "reference": ref.kind if ref else None,
        "modes": scoring.mode_metrics(runs, scored, nav),
        "skipped_modes": inputs.skipped, "counts": inputs.counts, "initialization": inputs.init,
        "beacons": inputs.beacons, "raw_gnss": inputs.raw_gnss, "notes": inputs.notes,
        "f_c_hz": inputs.f_c_hz, "f_c_source": inputs.beacons.get("f_c_source"),
        "doppler_rate_sigma_floor_hz_s": options.doppler_rate_sigma_floor_hz_s, "gate_nis": options.gate_nis,
    }
    if options.gnss_latency_s == "estimate":
        L = nav.layout
        for mode, (_, res, _) in runs.items():
            if mode in metrics["modes"] and res.x.shape[0]:
                metrics["modes"][mode]["fix_latency_s"] = latency_estimate(res.x[-1], res.P_diag[-1], L)
    metrics["trajectory_files"] = report.write_geodetic_trajectories(out_dir, inputs, runs, nav.layout,
                                                                      source=str(folder))
    if options.reference_file is not None:
        from leonav_runtime.dataset.evaluate import score_reference_file

        metrics["reference_file"] = score_reference_file(
            options.reference_file, {m: r[1] for m, r in runs.items()}, inputs.fixes,
            inputs.epoch_utc.timestamp() if inputs.epoch_utc else None, inputs.origin, nav.layout, out_dir)
    report.write_outputs(out_dir, inputs, scored, metrics, ref, nav)
    return metrics
