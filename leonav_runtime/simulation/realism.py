"""Realism switches: the simulated truth differs from what the filter assumes.

Each switch is a scenario section (`[ephemeris_error]`, `[imu_errors]`, `[front_end]`: the carrier
phase's C/N0, LO phase noise and cycle slips, front_end.py), off by default.
`enabled` changes the truth the sensors see; the compensation keys change only the filter,
so "errors on, no compensation", "errors on, compensated" and "compensation alone" can
all be run. Draws come from the trial's stream after every draw of the ideal simulation,
so with the switches off a trial is unchanged bit for bit.

Ephemeris error: every satellite's true orbit is offset from the one its elements give,
by a constant radial / along-track / cross-track error per satellite and trial (the
orbit error is correlated over an orbit, ~95 min for Starlink, so constant over the short
runs simulated here). The along-track part is a time shift of the state (r, v, a stay
consistent), radial and cross-track parts shift the position. Starlink sigmas grow with
element age as (age / reference_age)^k. The measurement is evaluated with the generated
model at the true orbit; the filter keeps the element orbit. Compensation `inflate-r`:
each measurement's sigma grows by the spread the orbit error causes in it (the model
evaluated with the satellite moved by one sigma along each axis), which treats an error
that is constant over the run as if it were white. Compensation `consider`: R + J P_sat J^T
with J the generated Jacobian of h over the aux satellite state and P_sat the linearised
orbit-error model (inputs/consider.py), added on the input road at the filter's prior state
(not the truth); `consider_correlation_s` > 0 scales it by the records of the satellite
within that time (the error is shared by a satellite's records: see docs/scenarios.md).

IMU errors the filter does not model: per-axis scale factors, misalignment (cross-axis
terms), gyro g-sensitivity (rad/s per m/s^2 of specific force) and bias drift with a
temperature ramp, all drawn per trial. Compensation: the filter's VRW, ARW and bias
random walks times `process_noise_inflation`.
"""
from __future__ import annotations

import numpy as np

from leonav_runtime.core import model, orbit_states
from leonav_runtime.inputs.consider import OrbitConsider, rac_axes  # noqa: F401  (rac_axes: re-exported)
from leonav_runtime.simulation import base_station, front_end
from leonav_runtime.simulation.orbit_truth import (  # noqa: F401  (the truth's names, re-exported)
    draw_orbit_errors, ephemeris_delta, ephemeris_sigma, perturb_states, sigma_rac,
    starlink_sigma_rac)



def _satellite_constellations() -> dict[str, str]:
    """Simulated satellite observable -> its constellation (registry)."""
    return {o.suffix: o.constellation for o in model.OBSERVABLES if o.table == "satellite"}


def orbit_consider(scn) -> OrbitConsider | None:
    """The road's consider term for `compensate = "consider"`: the sigmas of the perturbed
    constellations per observable kind. Under `compensate = "states"` the kinds whose satellites'
    offsets are states (`orbit_states.offset_kinds`) get none; the others the orbit error also
    reaches (a differenced range, GPS with `apply_to` gps) keep the consider term. None for any
    other compensation."""
    eph = scn.realism.get("ephemeris", {})
    if eph.get("compensate") not in ("consider", "states"):
        return None
    estimated = orbit_states.offset_observables() if eph["compensate"] == "states" else set()
    # a kind the base corrects in the orbit domain has its served covariance's term already (base_station.py)
    kinds = {k: c for k, c in _satellite_constellations().items()
             if c in eph["apply_to"] and not base_station.orbit_corrected(scn, k) and k not in estimated}
    covariance = {}
    if eph.get("operator_folder"):   # Starlink's P_sat from its operator ephemerides (docs/ephemerides.md)
        # imported on use: ERFA and the operator readers cost ~60 ms of import every sweep would pay
        from leonav_runtime.orbits.operator_consider import folder_covariance
        from leonav_runtime.simulation.visibility import scenario_elements
        provider = folder_covariance(eph["operator_folder"], scenario_elements(scn)["starlink"], scn.epoch_utc)
        covariance = {k: provider for k, c in kinds.items() if c == "starlink"}
    return OrbitConsider({k: sigma_rac(eph, c) for k, c in kinds.items()}, eph.get("consider_correlation_s", 0.0),
                         covariance)


def imu_error_increments(rng: np.random.Generator, cfg: dict, u_true: np.ndarray, t_start: np.ndarray,
                         dt: float, layout) -> np.ndarray:
    """Increments (n, 6) the unmodelled IMU errors add to the ideal ones u_true (n, 6):
    scale factor and misalignment of both triads, gyro g-sensitivity and the bias drift of a
    temperature ramp (t_start: start of each interval, s). Draw order: scale factors,
    misalignments, g-sensitivity, temperature coefficients."""
    g_sl, a_sl = layout.U_DTHETA_B_SLICE, layout.U_DVEL_B_SLICE
    s_a, s_g = (rng.standard_normal(3) * cfg[k] for k in ("accel_scale_factor", "gyro_scale_factor"))
    m_a, m_g = (rng.standard_normal((3, 3)) * cfg["misalignment_rad"] for _ in range(2))
    np.fill_diagonal(m_a, 0.0)
    np.fill_diagonal(m_g, 0.0)
    G = rng.standard_normal((3, 3)) * cfg["g_sensitivity_rad_s_per_mps2"]
    k_a = rng.standard_normal(3) * cfg["accel_bias_tempco_mps2_per_c"]
    k_g = rng.standard_normal(3) * cfg["gyro_bias_tempco_rad_s_per_c"]
    dtheta, dvel = u_true[:, g_sl], u_true[:, a_sl]
    temp = (cfg["temperature_rate_c_per_s"] * (t_start + 0.5 * dt))[:, None]   # degC above the start
    du = np.zeros_like(u_true)
    du[:, g_sl] = dtheta @ (np.diag(s_g) + m_g).T + dvel @ G.T + k_g * temp * dt
    du[:, a_sl] = dvel @ (np.diag(s_a) + m_a).T + k_a * temp * dt
    return du


def filter_params(params: np.ndarray, cfg: dict, layout) -> np.ndarray:
    """The filter's parameters with the IMU noise densities inflated (compensation)."""
    f = cfg["process_noise_inflation"]
    if f == 1.0:
        return params
    out = params.copy()
    for i in (layout.P_VRW, layout.P_ARW, layout.P_ACC_BIAS_RW, layout.P_GYRO_BIAS_RW):
        out[i] *= f
    return out


def apply(setup, nav, rng: np.random.Generator, u: np.ndarray,
          parts: list) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """Apply the scenario's switches to one trial: `parts` [kind_name, rows, z, sigma] are
    changed in place; returns the measured increments, the filter's parameters and the counts
    of what the front end did (slips injected and detected, epochs dropped; summed over parts)."""
    scn, L = setup.scn, nav.layout
    eph, imu = scn.realism.get("ephemeris", {}), scn.realism.get("imu", {})
    base = scn.realism.get("base", {})
    if eph.get("enabled"):
        errors = draw_orbit_errors(rng, setup)
        for part in parts:
            if model.observable(part[0]).constellation in eph["apply_to"]:
                part[2] = part[2] + ephemeris_delta(setup, nav, part[0], part[1], errors)
    if imu.get("enabled"):
        dt = 1.0 / scn.imu_rate_hz
        u = u + imu_error_increments(rng, imu, setup.u_true, setup.t_imu[:-1], dt, L)
    params = filter_params(setup.params, imu, L) if imu else setup.params
    fe, counts = scn.realism.get("front_end", {}), {}
    if fe.get("enabled"):   # before R grows: the front end's sigma is the tone's own
        for part in parts:
            if model.observable(part[0]).reads_interval:
                for key, n in front_end.apply(setup, rng, part, setup.series[part[0]]).items():
                    counts[key] = counts.get(key, 0) + n
    inflate = eph.get("compensate") == "inflate-r"
    if base.get("enabled"):   # the base sees the same true orbits: its corrections, applied (base_station.py)
        base_station.apply(setup, nav, rng, parts, errors)
    if inflate:
        for part in parts:
            o = model.observable(part[0])
            if o.constellation in eph["apply_to"] and not (base.get("enabled") and o.constellation == "starlink"):
                part[3] = np.sqrt(part[3] ** 2 + ephemeris_sigma(setup, nav, part[0], part[1]) ** 2)
    if fe.get("compensate"):
        params = params.copy()
        params[L.P_Q_BLO] = max(params[L.P_Q_BLO], front_end.filter_q_blo(fe, 1.0 / scn.starlink["rate_hz"]))
    return u, params, counts


def active(scn) -> bool:
    """Whether any switch or compensation changes a trial of `scn`."""
    eph, imu = scn.realism.get("ephemeris", {}), scn.realism.get("imu", {})
    fe, base = scn.realism.get("front_end", {}), scn.realism.get("base", {})
    return bool(base.get("enabled") or eph.get("enabled") or eph.get("compensate", "none") != "none" or imu.get("enabled")
                or imu.get("process_noise_inflation", 1.0) != 1.0 or fe.get("enabled") or fe.get("compensate"))

