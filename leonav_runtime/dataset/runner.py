"""A loaded dataset through the generated filter: parameters, coarse alignment, records, runs.

- Parameters: ENU origin = first fix; IMU white noise measured at the initial standstill
  (`[filter] imu_noise = "standstill"`) or a profile's; bias sigmas and random walks from
  `bias_profile`; the antenna lever arm (`[gnss] lever_arm_m`, to body FLU).
- Coarse alignment (`initial_state`): roll and pitch by the generated `leonav_level` from
  the specific force at the initial standstill (else the second before the start), gyro
  bias = the mean rate at that standstill minus the Earth rate in body axes; heading = the
  course of the GNSS velocity at the first time the vehicle moves (`[alignment] speed_mps`
  held for 1 s), where the filter starts, or a given yaw. Position = the antenna fix there minus the rotated lever arm.
- Records: IMU, fixes and the GNSS velocity (when the data has it; the `vel` stream) through
  `inputs.assemble` (the one road into the filter), plus the motion constraints
  (`constraints.py`); each mode merges the streams it names.
- Fix latency (`[gnss] time_offset_s`): a number is a known latency taken off the fix and
  velocity tags; "estimate" makes it the state `dt_fix` (prior `time_offset_prior_s` +-
  `time_offset_sigma_s`, random walk `time_offset_rw`), reported per mode with its sigma.
- No standstill at the start (the GNSS speed vetoes a quiet IMU): alignment in motion
  (`align.level_in_motion`: the specific force less the centripetal and along-track
  acceleration), heading from the GNSS course, the gyro bias from 0 with a wide prior
  (`MOVING_GYRO_BIAS_SIGMA_RADPS`); the report says which alignment was used and a note warns
  when levelling on the moving specific force would have been off by more than LEVEL_WARN_DEG.
- Time-correlated fix errors: `[gnss] rate_hz` thins the fixes; `sigma_scale = "auto"`
  runs the last mode once and rescales each fix axis's sigma once by sqrt(mean fix NIS of
  that axis), clamped, and not at all when that first run diverged (`auto_scale`; reported).
  This does not put the NIS mean of the second run in a band: it moves towards 1 but the
  rescale changes the gains, so it ends where it ends (reported per mode).
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

from leonav_runtime.core import filter as lfilter
from leonav_runtime.core import navfuncs, records
from leonav_runtime.dataset import align, checks, constraints, resets
from leonav_runtime.dataset.load import Dataset, ImuSamples
from leonav_runtime.core import model
from leonav_runtime.dataset.spec import dataset_mode
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gen.profiles import IMU_PROFILES
from leonav_runtime.inputs import FilterInputs, FixTable, ImuTable, Prior, VelocityTable, assemble, prior_sigmas
from leonav_runtime.core.params import ImuProfile, build_params

FIX_KINDS = ("POS_E", "POS_N", "POS_U")
MOVING_GYRO_BIAS_SIGMA_RADPS = math.radians(0.5)
"""Gyro bias prior sigma (rad/s) when no standstill measured it: a consumer MEMS gyro's turn-on bias."""
LEVEL_WARN_DEG = 1.0
"""Warn when levelling on the moving specific force would differ from the in-motion alignment by more."""


@dataclass
class Prepared:
    """Everything the runs share: inputs (IMU + fix records), constraint records per stream,
    the IMU samples on the run axis, all fixes (for the GPS-alone baseline), report items."""

    inputs: FilterInputs
    streams: dict[str, np.ndarray]
    imu: ImuSamples
    all_fixes: FixTable
    nav: navfuncs.NavFunctions
    gate: float
    report: dict = field(default_factory=dict)
    max_gap_s: float = 0.1          # [imu] max_gap_s
    lockout_fixes: int = 5          # [filter] lockout_fixes


def imu_table(imu: ImuSamples) -> ImuTable:
    """IMU intervals between consecutive samples, at the mean of their two samples' rates."""
    dt = np.diff(imu.t)
    w = 0.5 * (imu.w_b_radps[1:] + imu.w_b_radps[:-1])
    f = 0.5 * (imu.f_b_mps2[1:] + imu.f_b_mps2[:-1])
    return ImuTable.from_rates(imu.t[1:], dt, w, f)


def thin_fixes(fixes: FixTable, rate_hz: float) -> FixTable:
    """At most one fix per 1/rate_hz s bin (the first of the bin); all when rate_hz is 0."""
    if rate_hz <= 0 or fixes.t.size == 0:
        return fixes
    bins = np.floor(fixes.t * rate_hz + 1e-9)
    first = np.r_[True, bins[1:] != bins[:-1]]
    return fixes.select(first)


def _profile(spec, rest: align.Rest, report: dict) -> ImuProfile:
    f = spec["filter"]
    bias = IMU_PROFILES[f["bias_profile"]]
    if f["imu_noise"] == "standstill":
        if rest.vrw is None:
            raise UserInputError(f"{spec.where('filter', 'imu_noise')} = 'standstill': no standstill at the start "
                                 "of the IMU record: choose a profile (tactical, wt901)")
        vrw, arw, src = rest.vrw, rest.arw, f"measured over the first {rest.seconds:.2f} s at rest"
    else:
        white = IMU_PROFILES[f["imu_noise"]]
        vrw, arw, src = white.vrw, white.arw, f"profile {white.name}"
    report["imu_noise"] = {"vrw_mps_sqrts": vrw, "arw_rad_sqrts": arw, "source": src,
                           "bias_profile": bias.name}
    return ImuProfile("dataset", vrw, arw, bias.acc_bias_rw, bias.gyro_bias_rw, bias.acc_bias_sigma,
                      bias.gyro_bias_sigma, src)


def initial_state(ds: Dataset, imu: ImuSamples, rest: align.Rest, profile: ImuProfile, nav, report: dict,
                  notes: list[str] | None = None) -> Prior:
    """Prior at the filter start from the coarse alignment (module doc); warnings go to `notes`."""
    notes = notes if notes is not None else []
    spec, L = ds.spec, nav.layout
    al = spec["alignment"]
    t_v, v = align.gnss_velocity(ds.fixes, al["window_s"])
    k = align.moving_start(t_v, v, al["speed_mps"], 1.0)
    if al["yaw_rad"] is None and k is None:
        raise UserInputError(f"{spec.where('alignment', 'yaw_deg')} = 'gnss': the GNSS speed never stays above "
                             f"{al['speed_mps']} m/s for 1 s: give yaw_deg")
    t_start = max(float(t_v[k]) if k is not None else float(imu.t[0]), float(imu.t[0]), float(ds.fixes.t[0]))
    if imu.t[-1] < t_start + 1.0:
        raise UserInputError(f"the IMU ends at {imu.t[-1]:.6g} s, before the filter start at {t_start:.6g} s (the "
                             "vehicle first moves) + 1 s: expected a longer record, or --until beyond that")
    if al["yaw_rad"] is None:
        j = int(np.searchsorted(t_v, t_start))
        yaw, yaw_src = float(np.arctan2(v[j, 1], v[j, 0])), f"GNSS course at t={t_start:.2f} s"
    else:
        yaw, yaw_src = al["yaw_rad"], "given"
    if rest.n:
        kind = "static"
        f_level, level_src = rest.f_mean, f"specific force over the initial standstill ({rest.seconds:.2f} s)"
        roll, pitch = nav.level(f_level)
    else:
        kind = "in motion"
        roll, pitch, moving = align.level_in_motion(imu, ds.fixes, t_v, v, t_start, yaw, al["window_s"], nav)
        level_src = (f"specific force over {al['window_s']:g} s at the start less the vehicle's acceleration "
                     f"({np.linalg.norm(moving['accel_enu_mps2']):.2f} m/s^2: centripetal from the gyro and GNSS "
                     "velocity, along-track from the fixes) rotated to the body (in motion)")
        if moving["naive_error_deg"] > LEVEL_WARN_DEG:
            notes.append(f"WARNING: no standstill at the start: levelling on the moving specific force would be off by "
                         f"{moving['naive_error_deg']:.1f} deg (roll/pitch); the alignment removed the GNSS "
                         "acceleration (in-motion alignment)")
        report["alignment_in_motion"] = moving
    x0 = np.zeros(L.NX)
    q = nav.quat_from_euler(np.array([roll, pitch, yaw]))[0]
    x0[L.X_Q_NB_SLICE] = q
    # the generated fix model at p = 0 gives the rotated lever arm C_b_n l_b (nav.params hold l_b)
    aux = np.zeros(L.NAUX)
    lever_enu = np.array([nav.h(k, x0, aux)[0] for k in FIX_KINDS])
    antenna = np.array([np.interp(t_start, ds.fixes.t, ds.fixes.p_enu_m[:, j]) for j in range(3)])
    x0[L.X_P_ENU_SLICE] = antenna - lever_enu
    jv = int(np.clip(np.searchsorted(t_v, t_start), 0, max(t_v.size - 1, 0)))
    if t_v.size:
        x0[L.X_V_ENU_SLICE][:2] = v[jv, :2]
    # at rest the gyro measures its bias plus the Earth's rotation (7.3e-5 rad/s) in body axes of the
    # aligned attitude (level from gravity, heading from the later GNSS course): the rate the generated
    # mechanization needs to keep that attitude at rest
    if spec["gnss"]["time_offset_s"] == "estimate":
        x0[L.X_DT_FIX] = spec["gnss"]["time_offset_prior_s"]
    if rest.n:
        at_rest = x0.copy()
        at_rest[L.X_V_ENU_SLICE] = 0.0
        dt = 0.01
        w_ie_b = lfilter.stationary_imu(at_rest, dt, nav.params, nav.library)[L.U_DTHETA_B_SLICE] / dt
        x0[L.X_B_G_SLICE] = rest.gyro_mean - w_ie_b
    f = spec["filter"]
    i_fix = int(np.clip(np.searchsorted(ds.fixes.t, t_start), 0, ds.fixes.t.size - 1))
    overrides = {}
    if not rest.n:   # no standstill to measure the gyro bias: the filter estimates it from a wide prior
        overrides["db_g"] = max(profile.gyro_bias_sigma, MOVING_GYRO_BIAS_SIGMA_RADPS)
    if spec["gnss"]["time_offset_s"] == "estimate":
        overrides["ddt_fix"] = spec["gnss"]["time_offset_sigma_s"]
    sig = prior_sigmas(L, profile, ds.fixes.sigma_enu_m[i_fix], f["velocity_sigma_mps"],
                       [f["roll_pitch_sigma_rad"]] * 2 + [al["yaw_sigma_rad"]], overrides)
    report["alignment"] = {"kind": kind, "start_s": t_start,
                           "roll_pitch_yaw_deg": np.degrees([roll, pitch, yaw]).tolist(),
                           "gyro_bias_source": ("mean rate at the standstill less the Earth rate" if rest.n else
                                                f"none measured (no standstill): 0 with a prior sigma of "
                                                f"{math.degrees(overrides['db_g']):.2f} deg/s, left to the filter"),
                           "roll_pitch": f"generated leonav_level on the {level_src}", "yaw": yaw_src,
                           "gyro_bias_radps": x0[L.X_B_G_SLICE].tolist(),
                           "velocity_enu_mps": x0[L.X_V_ENU_SLICE].tolist()}
    return Prior(x0, np.diag(sig**2), dict(report["alignment"]), t_start)


def time_offset(ds: Dataset, report: dict) -> float:
    """The IMU time offset to use (s): given; "calibrate": `align.calibrate_time_offset` against
    the GNSS course; "calibrate_reference": against the reference's yaw (an explicit opt-in: the
    reference is what the run is scored on, so the result says so). Both estimates are reported
    whenever they can be made."""
    spec = ds.spec
    given = spec["imu"]["time_offset_s"]
    imu0 = ds.imu_on_axis(0.0)
    al = spec["alignment"]
    cal = {"gnss_course": align.calibrate_time_offset(
        imu0.t, imu0.w_b_radps[:, 2], *align.heading_source_gnss(ds.fixes, al["window_s"], 1.5 * al["speed_mps"]))}
    if ds.reference is not None and ds.reference.yaw_rad is not None:
        cal["reference_yaw"] = align.calibrate_time_offset(imu0.t, imu0.w_b_radps[:, 2], ds.reference.t,
                                                           ds.reference.yaw_rad)
    report["time_offset_calibration"] = cal
    where = spec.where("imu", "time_offset_s")
    if given == "calibrate_reference" and "reference_yaw" not in cal:
        raise UserInputError(f"{where} = 'calibrate_reference': the reference has no attitude "
                             "([reference] quaternion_columns): use 'calibrate' (GNSS course) or a number")
    if isinstance(given, str):
        key = "reference_yaw" if given == "calibrate_reference" else "gnss_course"
        best = cal[key]
        if best.get("offset_s") is None:
            raise UserInputError(f"{where} = {given!r}: {best.get('reason')}: give the offset in s")
        src = ("calibrated on the REFERENCE yaw (opt-in; the scores use the same reference)" if key == "reference_yaw"
               else "calibrated on the GNSS course")
        report["time_offset_s"] = {"value": best["offset_s"], "source": src, "uses_reference": key == "reference_yaw"}
        return float(best["offset_s"])
    report["time_offset_s"] = {"value": given, "source": "given ([imu] time_offset_s)", "uses_reference": False}
    return float(given)


def prepare(ds: Dataset, nav: navfuncs.NavFunctions | None = None, t_end_s: float | None = None) -> Prepared:
    """Parameters, alignment, records of every stream (module doc); t_end_s cuts the run (s)."""
    spec = ds.spec
    report: dict = {}
    given = spec["imu"]["time_offset_s"]
    off0 = 0.0 if isinstance(given, str) else float(given)
    checks.time_overlap(spec, ds.imu_on_axis(off0).t, ds.fixes.t, off0)
    offset = time_offset(ds, report)
    imu = ds.imu_on_axis(offset)
    if t_end_s is not None:
        checks.until(t_end_s, float(imu.t[0]) + 1.0, "the IMU starts (+ 1 s)")
        keep = imu.t <= t_end_s
        imu = ImuSamples(imu.t[keep], imu.w_b_radps[keep], imu.f_b_mps2[keep])
    all_fixes = shift_fixes(ds.fixes, spec["gnss"]["time_offset_s"])   # a known latency off the tags
    con = spec["constraints"]
    still = align.standstill(imu, con["standstill_window_s"], con["standstill_accel_std_mps2"],
                             con["standstill_gyro_std_radps"])
    # a quiet IMU is not a standstill while the fixes move (a smooth straight drive is quiet too)
    still, vetoed = align.veto_moving(still, imu.t, all_fixes, spec["alignment"]["window_s"],
                                      spec["alignment"]["speed_mps"])
    report["standstill_vetoed_by_gnss_speed_s"] = vetoed
    rest = align.initial_rest(imu, still, spec["alignment"]["static_max_s"])
    profile = _profile(spec, rest, report)
    latency = fix_latency(spec, report)
    params = np.asarray(build_params(*ds.origin, imu=profile, lever_b_m=tuple(spec["gnss"]["lever_arm_flu_m"]),
                                     values=sensor_params(spec) | latency))
    nav = nav or navfuncs.NavFunctions(params=params)
    nav.params = params
    notes = list(ds.notes)
    moved = dataclasses.replace(ds, fixes=all_fixes)
    prior = initial_state(moved, imu, rest, profile, nav, report, notes)
    table, _ = imu_table(imu).from_time(prior.t_start_s)
    fixes = thin_fixes(all_fixes, spec["gnss"]["rate_hz"])
    scale = spec["gnss"]["sigma_scale"]
    fixes = FixTable(fixes.t, fixes.p_enu_m, fixes.sigma_enu_m * (1.0 if isinstance(scale, str) else scale),
                     fixes.v_en_mps)
    velocity = velocity_table(ds, spec)
    inputs = assemble(table, params, prior, fixes=fixes, nav=nav, notes=notes, origin=ds.origin,
                      local=ds.local_on_axis(offset), velocity=velocity)
    streams = constraints.records_for(imu, still, prior.t_start_s, float(imu.t[-1]), con, nav)
    report["standstill"] = {"seconds": float(np.sum(np.diff(imu.t)[still[1:]])), "initial_s": rest.seconds}
    dt = np.diff(imu.t[imu.t >= prior.t_start_s])
    short = (dt > 2.5 * np.median(dt)) & (dt <= spec["imu"]["max_gap_s"]) if dt.size else dt.astype(bool)
    long = dt > spec["imu"]["max_gap_s"]
    report["imu_gaps"] = {"bridged_by_one_imu_step": int(short.sum()), "long": int(long.sum()),
                          "long_seconds": float(dt[long].sum()), "max_gap_s": spec["imu"]["max_gap_s"],
                          "long_handling": "constant-velocity predict, covariance inflated (dataset/resets.py)"}
    streams |= {token: inputs.records[token] for token in inputs.local}
    if velocity is not None:
        streams["vel"] = inputs.records["vel"]
    wants_vel = [m for m in spec["filter"]["modes"] if "vel" in dataset_mode(m).streams]
    if wants_vel and velocity is None:
        raise UserInputError(f"{spec.where('filter', 'modes')}: {', '.join(wants_vel)} use the GNSS velocity (vel): "
                             f"expected {spec.where('gnss', 'velocity_columns')} (or an NMEA/UBX log with velocity)")
    prep = Prepared(inputs, {"fix": inputs.records["fix"]} | streams, imu, all_fixes, nav,
                    spec["filter"]["gate_nis"], report, spec["imu"]["max_gap_s"], spec["filter"]["lockout_fixes"])
    if isinstance(scale, str):
        auto_scale(prep, spec["filter"]["modes"][-1])
    report["fix_sigma_scale"] = prep.report.get("fix_sigma_scale", {"value": scale, "source": "given"})
    return prep


def fix_latency(spec, report: dict) -> dict[str, float]:
    """The fix latency parameters ({"dt_fix_rw": s/sqrt(s)}: the state moves only when estimated),
    and the report item: a known latency shifts the tags (`shift_fixes`), 'estimate' makes it a state."""
    g = spec["gnss"]
    if g["time_offset_s"] == "estimate":
        report["fix_latency"] = {"source": "estimated (state dt_fix)", "prior_s": g["time_offset_prior_s"],
                                 "prior_sigma_s": g["time_offset_sigma_s"], "random_walk_s_per_sqrts": g["time_offset_rw"]}
        return {"dt_fix_rw": g["time_offset_rw"]}
    report["fix_latency"] = {"source": "given ([gnss] time_offset_s): the fix tags are shifted by it",
                             "value_s": g["time_offset_s"]}
    return {"dt_fix_rw": 0.0}


def shift_fixes(fixes: FixTable, latency: float | str) -> FixTable:
    """Fixes with a known latency (s) taken off their tags (a fix tagged t is the antenna at t - latency);
    unchanged when the latency is estimated."""
    if isinstance(latency, str) or latency == 0.0:
        return fixes
    return FixTable(fixes.t - latency, fixes.p_enu_m, fixes.sigma_enu_m, fixes.v_en_mps)


def velocity_table(ds: Dataset, spec) -> VelocityTable | None:
    """The dataset's GNSS velocity (`Dataset.velocity`) as the filter's table, a known latency taken
    off its tags like the fixes'; None when the data has none."""
    vel = getattr(ds, "velocity", None)
    if vel is None or not np.size(vel.t):
        return None
    latency = spec["gnss"]["time_offset_s"]
    t = np.asarray(vel.t, float) - (0.0 if isinstance(latency, str) else latency)
    return VelocityTable(t, np.asarray(vel.v_enu_mps, float), np.asarray(vel.sigma_mps, float))


def sensor_params(spec) -> dict[str, float]:
    """The registry parameters a local sensor's section sets (e.g. [mag] declination_deg), SI."""
    out = {}
    for q in model.PARAMS:
        section, _, key = q.scenario.partition(".")
        if section in model.LOCAL_SENSORS:
            value = spec[section][key]
            out[q.name] = math.radians(value) if key.endswith("_deg") else float(value)
    return out


SCALE_BOUNDS = (0.2, 5.0)
"""Clamp of the automatic per-axis fix sigma factor."""
DIVERGED_GATED_FRACTION = 0.05
"""A first pass gating more than this fraction of its fixes (or resetting a gate lockout) diverged."""


def auto_scale(prep: Prepared, mode: str) -> None:
    """One rescale of each fix axis's sigma (E, N, U) by sqrt(mean NIS of that axis) in a first run
    of `mode`, clamped to SCALE_BOUNDS; none when that first run diverged (gate lockout resets,
    or more than DIVERGED_GATED_FRACTION of its fixes gated): the factors of a diverged run
    measure the divergence, not the fixes. Reported in `fix_sigma_scale`."""
    recs, res, _, rep = run_mode(prep, mode)
    ids = [prep.nav.kind_id(k) for k in FIX_KINDS]
    fixes = np.isin(res.kind, ids)
    gated = float(np.mean(res.status[fixes] == lfilter.STATUS_GATED)) if fixes.any() else 0.0
    diverged = rep["resets"]["gate_lockout"] > 0 or gated > DIVERGED_GATED_FRACTION
    fix = prep.streams["fix"].copy()
    factors, raw = {}, {}
    for kind in FIX_KINDS:
        k = prep.nav.kind_id(kind)
        nis = fix_nis(prep, res, (kind,))
        raw[kind] = math.sqrt(float(np.mean(nis))) if nis.size else 1.0
        factors[kind] = 1.0 if diverged else float(np.clip(raw[kind], *SCALE_BOUNDS))
        fix["R"][fix["kind"] == k] *= factors[kind] ** 2
    prep.streams["fix"] = fix
    src = (f"one rescale by sqrt of each axis's fix NIS mean in a first {mode} run, clamped to "
           f"{list(SCALE_BOUNDS)}")
    prep.report["fix_sigma_scale"] = {
        "value": factors, "first_pass_factors": raw, "first_pass_gated_fraction": gated,
        "first_pass_lockout_resets": rep["resets"]["gate_lockout"],
        "source": src + ("; NOT applied: the first run diverged (gate lockout or > "
                         f"{DIVERGED_GATED_FRACTION:.0%} of fixes gated), sigma as given" if diverged else "")}


def fix_nis(prep: Prepared, res: lfilter.RunResult, kinds=FIX_KINDS) -> np.ndarray:
    """NIS of the fix records (of `kinds`) that were applied or gated."""
    ids = [prep.nav.kind_id(k) for k in kinds]
    sel = np.isin(res.kind, ids) & ((res.status == lfilter.STATUS_APPLIED) | (res.status == lfilter.STATUS_GATED))
    return res.nis[sel]


def run_mode(prep: Prepared, mode: str, outage: tuple[float, float] | None = None):
    """(records, RunResult, filter CPU seconds, report) of one mode; fixes inside `outage` [start, end) s
    removed. Covariance resets at long IMU gaps and gate lockouts (`resets`), counted in the report
    with the measurements dropped inside IMU gaps."""
    parts = [prep.inputs.records["imu"]]
    for s in dataset_mode(mode).streams:
        r = prep.streams[s]
        if s == "fix" and outage is not None:
            r = r[(r["t"] < outage[0]) | (r["t"] >= outage[1])]
        parts.append(r)
    max_gap = prep.max_gap_s
    recs, dropped = resets.bridge_gaps(records.merge_records(*parts), max_gap)
    t0 = time.thread_time()     # CPU of this thread: a wall clock would count the machine's other load
    res, counts = resets.run(recs, prep.inputs.x0, prep.inputs.P0, prep.inputs.params, prep.nav.layout,
                             gate=prep.gate or None, library=prep.nav.library,
                             fix_ids=[prep.nav.kind_id(k) for k in FIX_KINDS], max_gap_s=max_gap,
                             lockout_fixes=prep.lockout_fixes)
    seconds = time.thread_time() - t0
    return recs, res, seconds, {"resets": counts, "measurements_dropped_in_imu_gaps": dropped}
