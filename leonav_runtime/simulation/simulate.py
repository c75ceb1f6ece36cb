"""Truth and sensor simulation for a scenario, through the generated models.

`prepare(scn)` does the work shared by every trial, once per scenario:
- truth: the intended motion (trajectory.py) is turned into ideal IMU increments by
  inverting the *generated* mechanization step by step (Newton on `leonav_mech`), and
  the truth state is the mechanization's own output, so the filter and the truth share
  one model;
- satellites (satellites.py): SGP4 states of GPS and Starlink at every measurement epoch,
  visibility and the satellite-selection rule, aux blocks (`inputs.satellite_aux`), and the
  noise-free measurements of every simulated satellite observable evaluated with the
  generated `h` at the true state (measuring sensors' states at zero);
- local sensors (barometer, magnetometer: registry `table = "local"`) used by a mode: their
  epochs at the rate of their scenario section.

`trial_records(setup, mode, count, rng)` then draws one trial: sensor-error truth through the
generated error dynamics (sensor_errors.py: IMU biases, receiver clock, LO offset, each
sensor's own bias), IMU white noise, measurement noise, GPS outages, and an initial estimate
drawn from the prior. The measuring sensors' states enter the satellite measurements through
the generated Jacobian H (the models are linear in them), so no per-trial model evaluation is
needed; a local sensor's measurements are its generated h at the trial's truth. The drawn
IMU increments and measurements become sensor tables and go the one road into the filter
every source takes (`leonav_runtime.inputs.assemble`), which builds the records.

Random numbers: the paper's blocks and observables draw from the trial's stream in their
historical order (common random numbers with every earlier result); a block or observable
added later draws from a stream of its own (sensor_errors.own_stream), so adding a sensor
changes no other draw.

Time stamping: IMU samples at k/rate_hz; GPS, Starlink and local-sensor epochs fall on IMU
sample times (as a receiver that tags measurements with its own clock), an IMU record carries
the increments over (t - dt, t].
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.core import model, navfuncs
from leonav_runtime.core.params import IMU_PROFILES
from leonav_runtime.inputs import (F_B_AVERAGE_S, SATELLITE_TABLES, ImuTable, LocalSensorTable, Prior, assemble,
                                   averaged_specific_force, filter_params, prior_sigmas)
from leonav_runtime.scenarios.load import Scenario, mode_of
from leonav_runtime.simulation import carrier_truth, realism, satellites
from leonav_runtime.simulation.satellites import SatSeries
from leonav_runtime.simulation.sensor_errors import (bias_walks, draw_truth_many, measured_increments,
                                                     measured_increments_many, own_stream)
from leonav_runtime.simulation.trajectory import motion
from leonav_runtime.simulation.visibility import needed_constellations, scenario_elements

__all__ = [
    "SatSeries", "Setup", "Trial", "truth", "needed_constellations", "scenario_elements", "prior_covariance",
    "bias_walks", "measured_increments", "prepare", "noise_sigma", "selected_rows", "trial_records",
    "F_B_AVERAGE_S", "prior_sigmas", "averaged_specific_force",
]


@dataclass
class Setup:
    """Everything shared by the trials of one scenario."""

    scn: Scenario
    params: np.ndarray
    t_imu: np.ndarray           # (n+1,) s, sample times; interval k is (t[k], t[k+1]]
    x_true: np.ndarray          # (n+1, NX) truth (sensor errors at zero)
    u_true: np.ndarray          # (n, 6) ideal increments of interval k
    series: dict[str, SatSeries]
    visible_min: dict[str, int]  # fewest satellites above the mask over the run
    P0: np.ndarray              # filter prior covariance (NDX, NDX)
    imu_profile: object
    notes: list[str] = field(default_factory=list)
    local_k: dict[str, np.ndarray] = field(default_factory=dict)   # local sensor -> its IMU sample indices
    f_b: np.ndarray | None = None   # (n+1, 3) true specific force at each sample (the latest interval's)


# ---- truth ----------------------------------------------------------------------------

def truth(scn: Scenario, params: np.ndarray, nav: navfuncs.NavFunctions):
    """Truth of the scenario's motion through the generated mechanization.

    Returns (t_imu (n+1,) s, x_true (n+1, NX), u_true (n, 6)): the ideal increments of each
    IMU interval solve the mechanization for the intended velocity and attitude, and the
    truth is the mechanization's own output (clock, LO and biases at zero).
    """
    dt = 1.0 / scn.imu_rate_hz
    n = int(round(scn.duration_s * scn.imu_rate_hz))
    t = np.arange(n + 1) * dt
    m = motion(scn, t)
    L = nav.layout
    x_target = np.zeros((n + 1, L.NX))
    x_target[:, L.X_P_ENU_SLICE] = m.p_enu_m
    x_target[:, L.X_V_ENU_SLICE] = m.v_enu_mps
    x_target[:, L.X_Q_NB_SLICE] = nav.quat_from_euler(m.rpy_rad)
    x_true = np.empty_like(x_target)
    x_true[0] = x_target[0]
    u_true = np.zeros((n, 6))
    u = J = None
    for k in range(n):
        u, J = nav.imu_increments(x_true[k], x_target[k + 1], dt, guess=u, jacobian=J)
        u_true[k] = u
        x_true[k + 1] = nav.mech(x_true[k], u, dt)
    return t, x_true, u_true


def prior_covariance(scn: Scenario, profile, layout) -> np.ndarray:
    """Filter prior P0 (NDX, NDX), diagonal, from the scenario's [filter] sigmas."""
    f = scn.filter
    return np.diag(prior_sigmas(layout, profile, f["initial_position_sigma_m"], f["initial_velocity_sigma_mps"],
                                f["initial_attitude_sigma_rad"]) ** 2)


def _used_local_sensors(scn: Scenario) -> tuple[str, ...]:
    return tuple(dict.fromkeys(t for m in scn.modes for t in mode_of(m).local_sensors))


def prepare(scn: Scenario, nav: navfuncs.NavFunctions | None = None) -> Setup:
    """Truth, satellite geometry and noise-free measurements shared by all trials."""
    nav = nav or navfuncs.NavFunctions()
    profile = IMU_PROFILES[scn.imu_profile]
    params = filter_params((scn.lat_rad, scn.lon_rad, scn.alt_m), profile, scn.starlink["carrier_hz"], scn.params)
    nav.params = params
    t_imu, x_true, u_true = truth(scn, params, nav)
    dt = 1.0 / scn.imu_rate_hz
    # specific force of the latest IMU interval at each sample (sample 0: first interval)
    dvel = u_true[:, nav.layout.U_DVEL_B_SLICE]
    f_b = np.vstack([dvel[:1], dvel]) / dt

    elements = scenario_elements(scn)
    needed = needed_constellations(scn)
    notes: list[str] = []
    rows, visible = {}, {"gps": 0, "starlink": 0}
    for constellation in ("gps", "starlink"):
        rows[constellation], visible[constellation] = (satellites.CONSTELLATION_ROWS[constellation](
            scn, nav, elements[constellation], t_imu, x_true, notes) if constellation in needed else ([], 0))
    n_max = max(scn.starlink["counts"])
    if "starlink" in needed and visible["starlink"] < n_max:
        raise UserInputError(
            f"{scn.source}: [starlink] counts asks for up to {n_max} satellites but only "
            f"{visible['starlink']} are above the {math.degrees(scn.starlink['elevation_mask_rad']):.0f} deg "
            f"mask at some Starlink epoch of this scenario; lower the counts or the mask"
        )
    if "gps" in needed and visible["gps"] < 4:
        raise UserInputError(
            f"{scn.source}: only {visible['gps']} GPS satellites above the mask at some epoch (need >= 4)"
        )
    series = {o.suffix: satellites.series(nav, o.suffix, satellites.observable_rows(o, rows[o.constellation]),
                                          x_true, f_b, scn) for o in satellites.satellite_observables()}
    local_k = {token: satellites.epochs(scn, scn.local[token]["rate_hz"], t_imu) for token in _used_local_sensors(scn)}
    return Setup(scn, params, t_imu, x_true, u_true, series, visible, prior_covariance(scn, profile, nav.layout),
                 profile, notes, local_k, f_b)


# ---- one trial ----------------------------------------------------------------------------

def noise_sigma(scn: Scenario, kind_name: str) -> float:
    """The 1-sigma of a simulated observable: its registry noise key in the scenario."""
    n = model.observable(kind_name).noise
    section = scn.local[n.section] if n.section in scn.local else getattr(scn, n.section)
    return math.radians(section[n.key]) if n.key.endswith("_deg") else section[n.key]


def selected_rows(setup: Setup, kind_name: str, count: int) -> np.ndarray:
    """Rows of a series used by a mode with `count` Starlink satellites (GPS: all, minus outages)."""
    s = setup.series[kind_name]
    if model.observable(kind_name).constellation == "gps":
        keep = np.ones(s.t_s.size, bool)
        end_s = setup.scn.duration_s
        for a, b in setup.scn.gps["outages"]:
            # [a, b): GPS is back at b; an outage reaching the run's end covers the last epoch too
            keep &= ~((s.t_s >= a) & ((s.t_s < b) | (b >= end_s)))
        return np.flatnonzero(keep)
    return np.flatnonzero(s.rank < count)


@dataclass
class Trial:
    """One trial's inputs: the record stream, the filter's initial state, the truth state."""

    records: np.ndarray
    x0: np.ndarray
    x_true: np.ndarray   # (n+1, NX) truth including this trial's sensor errors
    params: np.ndarray | None = None   # the filter's parameters (realism compensation), else the setup's
    counts: dict[str, int] = field(default_factory=dict)   # the front end's slips and dropped epochs


def local_values(setup: Setup, nav, rng, mode, x_true: np.ndarray, g: float):
    """The mode's local sensors: [(token, z (epochs, observables), sigma (observables,))], each
    the generated h at the trial's truth plus noise (each observable's own stream)."""
    L, out = nav.layout, []
    for token in mode.local_sensors:
        k = setup.local_k[token]
        obs = [o for o in mode.observables if o.token == token]
        aux = np.zeros((k.size, L.NAUX))
        aux[:, L.AUX_F_B_SLICE] = setup.f_b[k]
        z = np.empty((k.size, len(obs)))
        sigma = np.empty(len(obs))
        for i, o in enumerate(obs):
            z[:, i] = nav.h_many(o.suffix, x_true[k], aux, params=setup.params, jacobian=False)[0]
            sigma[i] = noise_sigma(setup.scn, o.suffix)
            z[:, i] += g * sigma[i] * own_stream(rng, o.name).standard_normal(k.size)
        out.append((token, z, sigma))
    return out


@dataclass
class Draws:
    """The random part of B trials before it becomes tables: the sensor-error truth per block
    (B, n+1, size), the measured IMU increments u (B, n, 6), per used satellite observable
    [kind_name, rows, z (B, rows), sigma], and the filter's initial states x0 (B, NX)."""

    errors: dict[str, np.ndarray]
    u: np.ndarray
    parts: list
    x0: np.ndarray


def with_errors(x_base: np.ndarray, errors: dict[str, np.ndarray], trials: int) -> np.ndarray:
    """The truth (trials, n+1, NX): x_base (n+1, NX) with each sensor-error block replaced by its
    drawn truth (trials, n+1, size)."""
    x_true = np.empty((trials,) + x_base.shape)
    x_true[:] = x_base
    for name, values in errors.items():
        b = model.state_block(name)
        x_true[..., b.offset:b.offset + b.size] = values
    return x_true


def prior_draws(rngs: list[np.random.Generator], cov: np.ndarray) -> np.ndarray:
    """(B, m): trial i's `rngs[i].multivariate_normal(0, cov)`, the same values (numpy's SVD
    method: one standard normal draw of m per trial times the factor u sqrt(s)), with the
    factorisation made once for all trials instead of once per trial."""
    u, s, _ = np.linalg.svd(cov)
    factor_t = (u * np.sqrt(s)).T
    zero = np.zeros(cov.shape[0])
    # one row per product, as numpy's own: a product of several rows may round differently
    return np.stack([zero + r.standard_normal(cov.shape[0]).reshape(1, -1) @ factor_t for r in rngs])[:, 0]


def block_draws(setup: Setup, parsed, count: int, rngs: list[np.random.Generator], nav: navfuncs.NavFunctions,
                g: float = 1.0) -> Draws:
    """Every draw of B trials except the realism switches', trial i from rngs[i] in the order of
    the module doc (each stream sees the same draws whatever B), and the values they make, as
    arrays over the trials: shared by `trial_records` (B = 1) and the block builder
    (trial_block.py). g = 0: no noise, no biases, x0 at the truth (the draws are still made)."""
    scn, L, prof = setup.scn, nav.layout, setup.imu_profile
    n = setup.u_true.shape[0]
    dt = 1.0 / scn.imu_rate_hz
    Phi, Qd = nav.sensor_error_step(dt, setup.params)
    # a block of its own stream is drawn only when the mode measures it: no other draw depends on
    # it, and a sensor the mode does not have leaves its state at the base truth (error-free start)
    read = {name for o in parsed.observables for name in o.reads}
    drawn = {b.name for b in model.STATES if b.role != "navigation"
             and (b.truth["stream"] != "own" or b.role != "measurement" or b.error_name in read)}
    errors = draw_truth_many(rngs, [b for b in model.STATES if b.name in drawn], n, dt, Phi, Qd, scn, prof, L, g)
    zero = np.zeros((len(rngs), n + 1, 3))
    u = measured_increments_many(rngs, prof, setup.u_true, errors.get("b_a", zero), errors.get("b_g", zero), dt, g)
    measuring = [b for b in model.STATES if b.role == "measurement"]
    parts = []   # [kind_name, rows, z, sigma]
    for o in satellites.satellite_observables():
        s = setup.series[o.suffix]
        sigma = noise_sigma(scn, o.suffix)
        # the paper's observables draw for every series from the trial's stream (common numbers);
        # one with a stream of its own draws only when the mode uses it (no other draw depends on it)
        if not o.paper and o not in parsed.observables:
            continue
        noise = np.stack([(r if o.paper else own_stream(r, o.name)).standard_normal(s.t_s.size) for r in rngs])
        if o not in parsed.observables:
            continue
        rows = selected_rows(setup, o.suffix, count)
        k = np.rint(s.t_s[rows] * scn.imu_rate_hz).astype(int)
        # measuring sensors' states enter linearly: z = h(truth at zero) + H . (their true values)
        z = np.empty((len(rngs), rows.size))
        z[:] = s.z_true[rows]
        for b in measuring:
            if b.error_name in o.reads:
                for j in range(b.size):
                    value = errors[b.name][:, k, j] if b.name in errors else setup.x_true[k, b.offset + j]
                    z += s.H[rows, b.error_offset + j] * value
        if o.reads_interval:   # a time-differenced phase: its exact truth, not h's linear terms
            z = carrier_truth.trial_values(s.z_true[rows], k, s.k_prev[rows], errors, setup.x_true, dt)
        z += g * sigma * noise[:, rows]
        parts.append([o.suffix, rows, z, sigma])

    # the initial error is drawn over the states with a prior: the paper's blocks from the trial's
    # stream (as before any block was added), a block of its own stream from that stream
    dx0 = np.zeros((len(rngs), L.NDX))
    if g:
        var = np.diag(setup.P0)
        own = {b.name for b in model.STATES if b.truth["stream"] == "own"}
        shared = np.array([i for b in model.STATES if b.name not in own
                           for i in range(b.error_offset, b.error_offset + b.error_size) if var[i] > 0], int)
        dx0[:, shared] = prior_draws(rngs, setup.P0[np.ix_(shared, shared)])
        for b in model.STATES:
            e = slice(b.error_offset, b.error_offset + b.error_size)
            if b.name in own and b.name in drawn and np.any(var[e] > 0):
                dx0[:, e] = np.sqrt(var[e]) * np.stack([own_stream(r, b.name + ":prior").standard_normal(b.error_size)
                                                        for r in rngs])
    x_start = np.repeat(setup.x_true[:1], len(rngs), axis=0)
    for name, values in errors.items():
        b = model.state_block(name)
        x_start[:, b.offset:b.offset + b.size] = values[:, 0]
    return Draws(errors, u, parts, nav.boxplus_many(x_start, dx0))


def trial_records(setup: Setup, mode: str, count: int, rng: np.random.Generator,
                  nav: navfuncs.NavFunctions | None = None, noise_free: bool = False) -> Trial:
    """Draw one trial of `mode` with `count` Starlink satellites (the one road; a block of trials
    at once: trial_block.py, the same records).

    The random draws are made in a fixed order for every mode and count, so trials with
    the same seed share IMU, clock and noise realisations (common random numbers).
    noise_free: no sensor noise, no biases, filter starts at the truth (used for the PCRB
    and for checks).
    """
    nav = nav or navfuncs.NavFunctions(params=setup.params)
    scn = setup.scn
    parsed = mode_of(mode)
    n = setup.u_true.shape[0]
    dt = 1.0 / scn.imu_rate_hz
    g = 0.0 if noise_free else 1.0
    d = block_draws(setup, parsed, count, [rng], nav, g)
    x_true = with_errors(setup.x_true, d.errors, 1)[0]
    u, params, counts = d.u[0], setup.params, {}
    parts = [[kind_name, rows, z[0], sigma] for kind_name, rows, z, sigma in d.parts]
    if not noise_free and realism.active(scn):   # truth != filter; draws after all of the above
        u, params, counts = realism.apply(setup, nav, rng, u, parts)
    imu = ImuTable(setup.t_imu[1:], np.full(n, dt), u)
    tables = [satellite_table(part[0], setup.series[part[0]], *part[1:]) for part in parts]
    local = [LocalSensorTable(token, setup.t_imu[setup.local_k[token]], z, sigma)
             for token, z, sigma in local_values(setup, nav, rng, parsed, x_true, g)]
    # the road every source takes: tables -> records (aux f_b averaged from these IMU increments)
    inputs = assemble(imu, params, Prior(d.x0[0], setup.P0), satellites=tables, nav=nav, local=local,
                      orbit_consider=None if noise_free else realism.orbit_consider(scn))
    return Trial(inputs.merged(parsed.streams), d.x0[0], x_true, params, counts)


def satellite_table(kind_name: str, s: SatSeries, rows: np.ndarray, z: np.ndarray, sigma: float,
                    moved: tuple | None = None):
    """The measurements of `rows` of a series as the road's satellite table of that kind; moved:
    (satellite states (n, 9), start positions (n, 3) or None) in place of the element orbit's (a
    base station's orbit corrections applied)."""
    sat9, prev = (s.sat_ecef[rows], None if s.sat_prev_r_m is None else s.sat_prev_r_m[rows]) if moved is None \
        else moved
    return SATELLITE_TABLES[kind_name](s.t_s[rows], s.sat_id[rows], z, sigma, sat9,
                                       s.ref_ecef[rows] if s.has_ref else None,
                                       None if s.interval_s is None else s.interval_s[rows], prev)
