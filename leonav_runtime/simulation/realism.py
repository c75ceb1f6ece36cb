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

from leonav_runtime.core import model
from leonav_runtime.inputs.consider import OrbitConsider, rac_axes
from leonav_runtime.inputs.measurements import aux_blocks
from leonav_runtime.simulation import front_end
from leonav_runtime.simulation.sensor_errors import own_stream



def _satellite_constellations() -> dict[str, str]:
    """Simulated satellite observable -> its constellation (registry)."""
    return {o.suffix: o.constellation for o in model.OBSERVABLES if o.table == "satellite"}


def starlink_sigma_rac(eph: dict) -> np.ndarray:
    """Starlink radial, along, cross 1-sigma (m) at the configured element age."""
    age = max(eph["element_age_days"], 1.0 / 24.0)   # an element set is at least an hour old in use
    return np.asarray(eph["starlink_sigma_rac_m"]) * (age / eph["reference_age_days"]) ** eph["growth_exponent"]


def sigma_rac(eph: dict, constellation: str) -> np.ndarray:
    return starlink_sigma_rac(eph) if constellation == "starlink" else np.asarray(eph["gps_sigma_rac_m"])


def perturb_states(state9: np.ndarray, d_rac: np.ndarray) -> np.ndarray:
    """True satellite states (n, 9) [r v a] (m, m/s, m/s^2, ECEF) from the element states and
    radial/along/cross offsets d_rac (n, 3) m: along-track as a time shift, the rest as offsets."""
    r, v, a = state9[:, 0:3], state9[:, 3:6], state9[:, 6:9]
    axes = rac_axes(state9)
    dt = (d_rac[:, 1] / np.einsum("ni,ni->n", v, axes[:, 1]))[:, None]   # s along the velocity
    out = state9.copy()
    out[:, 0:3] = r + v * dt + 0.5 * a * dt**2 + d_rac[:, :1] * axes[:, 0] + d_rac[:, 2:] * axes[:, 2]
    out[:, 3:6] = v + a * dt
    return out


def draw_orbit_errors(rng: np.random.Generator, setup) -> dict[str, dict[int, np.ndarray]]:
    """Per constellation, per NORAD id: radial/along/cross offsets (m) of this trial. Every
    satellite of the run gets one, in id order, whatever the mode (common random numbers)."""
    eph, out = setup.scn.realism["ephemeris"], {}
    for constellation in ("gps", "starlink"):
        kinds = [o.suffix for o in model.OBSERVABLES if o.table == "satellite" and o.constellation == constellation]
        ids = np.unique(np.concatenate([setup.series[k].sat_id for k in kinds]))
        d = rng.standard_normal((ids.size, 3)) * sigma_rac(eph, constellation)
        out[constellation] = dict(zip(ids.tolist(), d))
    return out


def _ref_ids(setup, kind_name: str, rows: np.ndarray) -> np.ndarray:
    """NORAD id of each row's reference satellite: the rank-0 satellite of its epoch, taken
    from a series of the same constellation that is not differenced, which holds every ranked
    satellite of every epoch (a differenced series has no rank-0 rows of its own)."""
    c = model.observable(kind_name).constellation
    ref = setup.series[next(o.suffix for o in model.OBSERVABLES
                            if o.table == "satellite" and o.constellation == c and not o.reads_ref)]
    top = ref.rank == 0
    by_t = dict(zip(ref.t_s[top].tolist(), ref.sat_id[top].tolist()))
    return np.array([by_t[t] for t in setup.series[kind_name].t_s[rows].tolist()], dtype=np.int64)


def _offsets(errors: dict[int, np.ndarray], ids: np.ndarray) -> np.ndarray:
    return np.array([errors[i] for i in ids.tolist()]).reshape(-1, 3)


def _model(setup, nav, kind_name: str, rows: np.ndarray, aux: np.ndarray) -> np.ndarray:
    k = np.rint(setup.series[kind_name].t_s[rows] * setup.scn.imu_rate_hz).astype(int)
    h, _ = nav.h_many(kind_name, setup.x_true[k], aux, params=setup.params, jacobian=False)
    return h


def _moved_aux(setup, kind_name: str, rows: np.ndarray, d_sat: np.ndarray, d_ref: np.ndarray | None,
               layout) -> np.ndarray:
    s = setup.series[kind_name]
    sat_block, ref_block, _ = aux_blocks(layout)
    aux = s.aux[rows].copy()
    aux[:, sat_block] = perturb_states(s.sat_ecef[rows], d_sat)
    if s.sat_prev_r_m is not None:   # a time difference: its start flies the same true orbit
        T = s.interval_s[rows][:, None]
        v, a = s.sat_ecef[rows, 3:6], s.sat_ecef[rows, 6:9]
        prev = np.concatenate([s.sat_prev_r_m[rows], v - a * T, a], axis=1)
        aux[:, layout.AUX_R_S_PREV_ECEF_SLICE] = perturb_states(prev, d_sat)[:, 0:3]
    if d_ref is not None:
        aux[:, ref_block] = perturb_states(s.ref_ecef[rows], d_ref)
    return aux


def ephemeris_delta(setup, nav, kind_name: str, rows: np.ndarray, errors: dict,
                    x_at: np.ndarray | None = None) -> np.ndarray:
    """Change (measurement unit) of each row's noise-free value when its satellite (and its
    reference) fly their true orbits instead of the element orbits; x_at (NX,): evaluated for
    a receiver at this state instead of the truth (a base station)."""
    s, constellation = setup.series[kind_name], model.observable(kind_name).constellation
    d_sat = _offsets(errors[constellation], s.sat_id[rows])
    d_ref = _offsets(errors[constellation], _ref_ids(setup, kind_name, rows)) if s.has_ref else None
    aux = _moved_aux(setup, kind_name, rows, d_sat, d_ref, nav.layout)
    if x_at is None:
        return _model(setup, nav, kind_name, rows, aux) - s.model_at_truth[rows]
    moved, _ = nav.h_many(kind_name, x_at, aux, params=setup.params, jacobian=False)
    element, _ = nav.h_many(kind_name, x_at, s.aux[rows], params=setup.params, jacobian=False)
    return moved - element


def base_corrections(setup, nav, rng: np.random.Generator, part: list, errors: dict) -> np.ndarray:
    """A base station's corrections (measurement unit) for one part [kind_name, rows, z, sigma]:
    what the orbit error does to the same observable at the base's known position (`[base]`
    offset from the site, at rest), plus the base's own noise (the part's sigma, its own
    stream), minus its mean over each epoch's satellites (the base's LO and clock are common to
    an epoch; the rover's own states take up what that removes). The rover subtracts them and
    adds their variance to R (simulation: corrections of the rover's epoch, age 0)."""
    kind_name, rows = part[0], part[1]
    delta = ephemeris_delta(setup, nav, kind_name, rows, errors, x_at=base_state(setup))
    sigma = np.broadcast_to(np.asarray(part[3], float), delta.shape)
    corr = delta + sigma * own_stream(rng, f"base:{kind_name}").standard_normal(delta.size)
    t = setup.series[kind_name].t_s[rows]
    _, index = np.unique(t, return_inverse=True)
    mean = np.bincount(index, corr) / np.bincount(index)
    return corr - mean[index]


def ephemeris_sigma(setup, nav, kind_name: str, rows: np.ndarray, x_base: np.ndarray | None = None) -> np.ndarray:
    """1-sigma (measurement unit) the orbit error adds to each row: the model's change with
    the satellite (and, independently, the reference) moved one sigma along each axis; with
    x_base (NX,), what is left after a base station at that state corrects it (the change at
    the receiver minus the change at the base)."""
    s = setup.series[kind_name]
    sig = sigma_rac(setup.scn.realism["ephemeris"], model.observable(kind_name).constellation)
    base = s.model_at_truth[rows]
    at_base = None if x_base is None else nav.h_many(kind_name, x_base, s.aux[rows], params=setup.params,
                                                     jacobian=False)[0]
    var = np.zeros(rows.size)
    for moved in (("sat", "ref") if s.has_ref else ("sat",)):
        for axis in range(3):
            d = np.zeros((rows.size, 3))
            d[:, axis] = sig[axis]
            zero = np.zeros_like(d)
            aux = _moved_aux(setup, kind_name, rows, d if moved == "sat" else zero,
                             (d if moved == "ref" else zero) if s.has_ref else None, nav.layout)
            change = _model(setup, nav, kind_name, rows, aux) - base
            if x_base is not None:
                change -= nav.h_many(kind_name, x_base, aux, params=setup.params, jacobian=False)[0] - at_base
            var += change**2
    return np.sqrt(var)


def base_state(setup) -> np.ndarray:
    """The base station's state (NX,): at rest at its `[base]` offset from the site."""
    x_base = setup.x_true[0].copy()
    x_base[0:3] = setup.scn.realism["base"]["offset_enu_m"]
    x_base[3:6] = 0.0
    return x_base


def orbit_consider(scn) -> OrbitConsider | None:
    """The road's consider term for `compensate = "consider"`: the sigmas of the perturbed
    constellations per observable kind (None for any other compensation)."""
    eph = scn.realism.get("ephemeris", {})
    if eph.get("compensate") != "consider":
        return None
    kinds = {k: c for k, c in _satellite_constellations().items() if c in eph["apply_to"]}
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


def apply(setup, nav, rng: np.random.Generator, u: np.ndarray, parts: list) -> tuple[np.ndarray, np.ndarray]:
    """Apply the scenario's switches to one trial: `parts` [kind_name, rows, z, sigma] are
    changed in place; returns the measured increments and the filter's parameters."""
    scn, L = setup.scn, nav.layout
    eph, imu = scn.realism.get("ephemeris", {}), scn.realism.get("imu", {})
    base = scn.realism.get("base", {})
    if eph.get("enabled"):
        errors = draw_orbit_errors(rng, setup)
        for part in parts:
            if model.observable(part[0]).constellation in eph["apply_to"]:
                part[2] = part[2] + ephemeris_delta(setup, nav, part[0], part[1], errors)
    if eph.get("compensate") == "inflate-r":   # with a base: what its corrections leave (below)
        for part in parts:
            if model.observable(part[0]).constellation in eph["apply_to"]:
                x_base = base_state(setup) if base.get("enabled") and \
                    model.observable(part[0]).constellation == "starlink" else None
                part[3] = np.sqrt(part[3] ** 2 + ephemeris_sigma(setup, nav, part[0], part[1], x_base) ** 2)
    if imu.get("enabled"):
        dt = 1.0 / scn.imu_rate_hz
        u = u + imu_error_increments(rng, imu, setup.u_true, setup.t_imu[:-1], dt, L)
    params = filter_params(setup.params, imu, L) if imu else setup.params
    fe = scn.realism.get("front_end", {})
    if fe.get("enabled"):
        for part in parts:
            if model.observable(part[0]).reads_interval:
                front_end.apply(setup, rng, part, setup.series[part[0]])
    if base.get("enabled"):   # the base sees the same true orbits: its corrections, applied
        for part in parts:
            if model.observable(part[0]).constellation == "starlink":
                part[2] = part[2] - base_corrections(setup, nav, rng, part, errors)
                part[3] = np.sqrt(2.0) * np.asarray(part[3], float)   # the base's noise beside the rover's
    if fe.get("compensate"):
        params = params.copy()
        params[L.P_Q_BLO] = max(params[L.P_Q_BLO], front_end.filter_q_blo(fe, 1.0 / scn.starlink["rate_hz"]))
    return u, params


def active(scn) -> bool:
    """Whether any switch or compensation changes a trial of `scn`."""
    eph, imu = scn.realism.get("ephemeris", {}), scn.realism.get("imu", {})
    fe, base = scn.realism.get("front_end", {}), scn.realism.get("base", {})
    return bool(base.get("enabled") or eph.get("enabled") or eph.get("compensate", "none") != "none" or imu.get("enabled")
                or imu.get("process_noise_inflation", 1.0) != 1.0 or fe.get("enabled") or fe.get("compensate"))

