"""A synthetic session run twice: replayed from its bytes, and directly from the floats that
went into it (`leonav session synth --compare`). The RMSE difference between the two runs is
what the byte formats and time tagging cost."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from leonav_runtime.core import navfuncs
from leonav_runtime.orbits import geometry
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.inputs import FixTable, ImuTable
from leonav_runtime.common.output import write_json
from leonav_runtime.replay.beacon_table import BeaconMeasurements
from leonav_runtime.replay.options import ReplayOptions, check_options
from leonav_runtime.replay.run import SessionInputs, decode_inputs, replay_session, run_modes, session_inputs
from leonav_runtime.replay.scoring import evaluate, mode_metrics, truth_reference
from leonav_runtime.replay.timebase import filter_profile
from leonav_runtime.simulation.session_synth import SyntheticSession


def direct_inputs(synth: SyntheticSession, replayed: SessionInputs, options: ReplayOptions | None = None,
                  nav: navfuncs.NavFunctions | None = None) -> SessionInputs:
    """The replay's inputs rebuilt from the floats that went into the session (no bytes).

    Same truth, same noise draws, same road into the filter (`replay.session_inputs`:
    initial fix, averaged specific force and its noise in the Doppler-rate R, prior), same
    carrier and same Doppler-rate values (the beacon pipeline's output of the replay, i.e.
    the same measurement errors), but: exact sample and fix times (no stamps, no time map),
    unquantized IMU values (so the filter's IMU noise is the plain WT901 profile), unrounded
    fixes and angles, and the Doppler-rate epochs at their true times. Fixes the session
    sent without an altitude are left out, as the replay does. The RMSE difference between
    the two runs is what the byte formats and time tagging cost.
    """
    options = check_options(options or ReplayOptions())
    nav = nav or navfuncs.NavFunctions()
    cfg = synth.cfg
    dt = 1.0 / cfg.imu_rate_hz
    lat0, lon0, h0 = synth.origin
    r_site = geometry.geodetic_to_ecef(lat0, lon0, h0)
    sent = synth.fix_t >= cfg.gga_no_altitude_s - 1e-9
    if not np.any(sent):
        raise UserInputError(f"{synth.folder}: no GNSS fix with an altitude: nothing to compare")
    r_fix = geometry.enu_to_ecef(synth.fix_enu[sent], r_site, lat0, lon0)
    lat, lon, h = geometry.ecef_to_geodetic(r_fix[0])
    origin = (float(lat), float(lon), float(h))
    enu = geometry.ecef_to_enu(r_fix, geometry.geodetic_to_ecef(*origin), origin[0], origin[1])
    n = synth.u_meas.shape[0]
    L = nav.layout
    imu = ImuTable.from_rates(synth.t_imu[1:], np.full(n, dt), synth.u_meas[:, L.U_DTHETA_B_SLICE] / dt,
                              synth.u_meas[:, L.U_DVEL_B_SLICE] / dt, synth.ahrs_rpy_rad)
    sig = np.tile([cfg.fix_sigma_en_m, cfg.fix_sigma_en_m, cfg.fix_sigma_u_m], (enu.shape[0], 1))
    fixes = FixTable(synth.fix_t[sent], enu, sig, synth.fix_vel_en[sent])
    # the replay's Doppler-rate epochs inside its IMU span, moved from its time axis to the truth's
    m = replayed.beacon_measurements
    inside = (m.t >= replayed.init["start_s"]) & (m.t <= replayed.imu.t[-1])
    t = m.t[inside]
    if t.size:
        start = replayed.beacons["capture_start_utc"].timestamp()
        t = cfg.sdr_start_s + (t + replayed.epoch_utc.timestamp() - start)   # capture seconds -> truth axis
    meas = BeaconMeasurements(t, m.norad_id[inside], m.sat_index[inside], m.z_hz_s[inside], m.sigma_hz_s[inside])
    inputs = session_inputs(cfg.epoch_utc, origin, imu, fixes, meas, synth.elements, options,
                            filter_profile(dt, quantized=False), nav, [], replayed.f_c_hz)
    inputs.skipped = dict(replayed.skipped)
    return inputs


def compare_replay_direct(synth: SyntheticSession, out_dir: str | Path, options: ReplayOptions | None = None,
                          elements=None, nav: navfuncs.NavFunctions | None = None) -> dict:
    """Replay the session (outputs in out_dir) and run the direct simulation; RMSE of both per mode.

    The session is decoded (and its capture processed) once; both runs use that decoding."""
    options = check_options(options or ReplayOptions(gnss_latency_s=synth.cfg.gnss_latency_s))
    nav = nav or navfuncs.NavFunctions()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    replayed = decode_inputs(synth.folder, options, elements or synth.elements, out_dir, nav)
    metrics = replay_session(synth.folder, out_dir, options, nav=nav, inputs=replayed)
    direct = direct_inputs(synth, replayed, options, nav)
    runs = run_modes(direct, options.modes, options.gate_nis, nav)
    ref = truth_reference(synth.folder / "truth.csv", direct.epoch_utc, direct.origin, nav)
    direct_metrics = mode_metrics(runs, evaluate(direct, runs, ref, nav), nav)
    keys = ("rmse_position_m", "rmse_velocity_mps", "rmse_attitude_deg")
    table = {mode: {k: {"replay": metrics["modes"][mode][k], "direct": direct_metrics[mode][k]} for k in keys}
             for mode in metrics["modes"] if mode in direct_metrics}
    write_json(out_dir / "replay_vs_direct.json", {"note": direct_inputs.__doc__.strip(), "rmse": table,
                                                  "direct": direct_metrics})
    return {"replay": metrics, "direct": direct_metrics, "table": table}
