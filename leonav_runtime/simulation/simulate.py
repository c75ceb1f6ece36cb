"""Truth and sensor simulation for a scenario, through the generated models.

`prepare(scn)` does the work shared by every trial, once per scenario:
- truth: the intended motion (trajectory.py) is turned into ideal IMU increments by
  inverting the *generated* mechanization step by step (Newton on `leonav_mech`), and
  the truth state is the mechanization's own output, so the filter and the truth share
  one model;
- satellites: SGP4 states of GPS and Starlink at every measurement epoch, visibility and
  the satellite-selection rule, aux blocks (`inputs.satellite_aux`), and the noise-free
  measurements evaluated with the generated `h` functions at the true state (clock and LO
  states at zero).

`trial_records(setup, mode, count, rng)` then draws one trial: IMU biases (random walks
from the profile) and white noise, receiver clock and LO offset (random walks from the
filter's own process model), measurement noise, GPS outages, and an initial estimate
drawn from the prior. Clock and LO enter the measurements through the generated Jacobian
H (the models are linear in those states), so no per-trial model evaluation is needed.
The drawn IMU increments and measurements become sensor tables and go the one road into
the filter every source takes (`leonav_runtime.inputs.assemble`), which builds the records.

Time stamping: IMU samples at k/rate_hz; GPS and Starlink epochs fall on IMU sample
times (as a receiver that tags measurements with its own clock), an IMU record carries
the increments over (t - dt, t].
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from leonav_runtime.core import navfuncs
from leonav_runtime.simulation import realism
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gen import state_layout
from leonav_runtime.inputs import (CLOCK_BIAS_SIGMA_M, CLOCK_DRIFT_SIGMA_MPS, F_B_AVERAGE_S,
                                   LO_OFFSET_SIGMA_HZ, LO_RANDOM_WALK_HZ2_S, SATELLITE_TABLES, ImuTable, Prior,
                                   assemble, averaged_specific_force, filter_params, prior_sigmas, satellite_aux,
                                   states_from_aux)
from leonav_runtime.simulation.visibility import (_receiver_ecef, _visible_ranked, needed_constellations,  # noqa: F401
                                           scenario_elements)
from leonav_runtime.core.params import IMU_PROFILES
from leonav_runtime.scenarios.load import MODE_OBSERVABLES, Scenario
from leonav_runtime.simulation.trajectory import motion
from leonav_runtime.simulation.sensor_errors import _random_walk, bias_walks, measured_increments  # noqa: F401  (public here too)

__all__ = [
    "SatSeries", "Setup", "Trial", "truth", "needed_constellations", "scenario_elements", "prior_covariance",
    "bias_walks", "measured_increments", "prepare", "noise_sigma", "selected_rows", "trial_records", "SERIES",
    # re-exported from `leonav_runtime.inputs` (the road into the filter), where they live
    "CLOCK_BIAS_SIGMA_M", "CLOCK_DRIFT_SIGMA_MPS", "F_B_AVERAGE_S", "LO_OFFSET_SIGMA_HZ", "LO_RANDOM_WALK_HZ2_S",
    "prior_sigmas", "averaged_specific_force",
]
SERIES = ("pseudorange", "doppler_rate", "doppler", "ofdm_range_diff")


@dataclass
class SatSeries:
    """Measurements of one observable over the run (one row per measurement).

    t_s, sat_id (NORAD id), aux (n, NAUX), z_true (noise-free, clock/LO states at zero),
    H (n, NDX) at the truth, rank (elevation rank at its epoch, 0 = highest); sat_ecef,
    ref_ecef: the satellite's and the reference's r, v, a of aux as contiguous (n, 9) blocks
    (`inputs.SAT_*` columns), what the trials' satellite tables are cut from.
    """

    kind: int
    t_s: np.ndarray
    sat_id: np.ndarray
    aux: np.ndarray
    z_true: np.ndarray
    H: np.ndarray
    rank: np.ndarray
    sat_ecef: np.ndarray = field(init=False, repr=False)
    ref_ecef: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.sat_ecef, self.ref_ecef = (np.ascontiguousarray(b) for b in states_from_aux(self.aux, state_layout))


@dataclass
class Setup:
    """Everything shared by the trials of one scenario."""

    scn: Scenario
    params: np.ndarray
    t_imu: np.ndarray           # (n+1,) s, sample times; interval k is (t[k], t[k+1]]
    x_true: np.ndarray          # (n+1, NX) truth (biases, clock and LO at zero)
    u_true: np.ndarray          # (n, 6) ideal increments of interval k
    series: dict[str, SatSeries]
    visible_min: dict[str, int]  # fewest satellites above the mask over the run
    P0: np.ndarray              # filter prior covariance (NDX, NDX)
    imu_profile: object
    notes: list[str] = field(default_factory=list)


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


# ---- satellites -------------------------------------------------------------------------

def _epochs(scn: Scenario, rate_hz: float, t_imu: np.ndarray) -> np.ndarray:
    """Measurement epochs on IMU sample times, from the first sample after 0."""
    step = int(round(scn.imu_rate_hz / rate_hz))
    if step < 1 or abs(scn.imu_rate_hz / rate_hz - step) > 1e-9:
        raise UserInputError(
            f"{scn.source}: measurement rate {rate_hz} Hz must divide the IMU rate "
            f"{scn.imu_rate_hz} Hz (measurements are tagged on IMU sample times)"
        )
    return np.arange(step, t_imu.size, step)


def _series(nav, kind_name, rows, x_true, f_b) -> SatSeries:
    """Rows (k, t, sat_id, satellite state (9,), reference state (9,) or None, rank) as a series:
    aux as the road builds it (`inputs.satellite_aux`, f_b of sample k), h and H at the truth."""
    n, L = len(rows), nav.layout
    k = np.array([r[0] for r in rows], int)
    sat = np.array([r[3] for r in rows]).reshape(n, 9)
    ref = np.array([r[4] for r in rows]).reshape(n, 9) if n and rows[0][4] is not None else None
    table = SATELLITE_TABLES[kind_name](np.array([r[1] for r in rows], float), np.array([r[2] for r in rows],
                                        np.int32), np.zeros(n), 1.0, sat, ref)
    aux = satellite_aux(table, f_b[k], L)
    kind = nav.kind_id(kind_name)
    z, H = np.empty(n), np.empty((n, L.NDX))
    for i in range(n):
        z[i], H[i] = nav.h(kind, x_true[k[i]], aux[i])
    return SatSeries(kind, table.t, table.sat_id, aux, z, H, np.array([r[5] for r in rows], np.int32))


def _gps_rows(scn, nav, es, t_imu, x_true, f_b, notes):
    idx = _epochs(scn, scn.gps["rate_hz"], t_imu)
    t = t_imu[idx]
    p_enu = x_true[idx, nav.layout.X_P_ENU_SLICE]
    states, ranked, _, es = _visible_ranked(scn, es, t, p_enu, scn.gps["elevation_mask_rad"], notes)
    r_rx = _receiver_ecef(scn, p_enu)
    rows = []
    for j, k in enumerate(idx):
        use = ranked[j][: scn.gps["max_satellites"]]
        for rank, s in enumerate(use):
            # Satellite at transmit time (generated light-time solution), in the ECEF frame
            # of the transmit epoch, as the pseudorange model (with Sagnac) expects.
            a = states.a_ecef_mps2[s, j]
            r_tx, v_tx, _ = nav.transmit_state(states.r_ecef_m[s, j], states.v_ecef_mps[s, j], a, r_rx[j])
            rows.append((k, t[j], int(es.norad_ids[s]), np.concatenate([r_tx, v_tx, a]), None, rank))
    vis = [len(r) for r in ranked]
    return rows, min(vis) if vis else 0


def _starlink_rows(scn, nav, es, t_imu, x_true, f_b, notes):
    idx = _epochs(scn, scn.starlink["rate_hz"], t_imu)
    t = t_imu[idx]
    p_enu = x_true[idx, nav.layout.X_P_ENU_SLICE]
    # Only satellites that can be above the mask need states at every epoch (`_candidates`).
    priority = None
    if scn.starlink["selection"] == "random":   # one draw per run: the tracked subset persists
        priority = np.random.default_rng(scn.starlink["selection_seed"]).random(len(es.norad_ids))
    states, ranked, _, es = _visible_ranked(scn, es, t, p_enu, scn.starlink["elevation_mask_rad"], notes,
                                        priority=priority)
    n_max = max(scn.starlink["counts"])
    doppler_rate, doppler, ofdm = [], [], []   # rows: see _series
    for j, k in enumerate(idx):
        use = ranked[j][:n_max]
        if use.size == 0:
            continue
        sat = np.concatenate([states.r_ecef_m[use, j], states.v_ecef_mps[use, j], states.a_ecef_mps2[use, j]],
                             axis=1)
        for rank, s in enumerate(use):
            row = (k, t[j], int(es.norad_ids[s]), sat[rank], sat[0], rank)
            doppler_rate.append(row)
            doppler.append(row)
            if rank > 0:  # differenced against the highest satellite (rank 0)
                ofdm.append(row)
    vis = [len(r) for r in ranked]
    return doppler_rate, doppler, ofdm, min(vis) if vis else 0


def prior_covariance(scn: Scenario, profile, layout) -> np.ndarray:
    """Filter prior P0 (NDX, NDX), diagonal, from the scenario's [filter] sigmas."""
    f = scn.filter
    return np.diag(prior_sigmas(layout, profile, f["initial_position_sigma_m"], f["initial_velocity_sigma_mps"],
                                f["initial_attitude_sigma_rad"]) ** 2)


def prepare(scn: Scenario, nav: navfuncs.NavFunctions | None = None) -> Setup:
    """Truth, satellite geometry and noise-free measurements shared by all trials."""
    nav = nav or navfuncs.NavFunctions()
    profile = IMU_PROFILES[scn.imu_profile]
    params = filter_params((scn.lat_rad, scn.lon_rad, scn.alt_m), profile, scn.starlink["carrier_hz"])
    nav.params = params
    t_imu, x_true, u_true = truth(scn, params, nav)
    dt = 1.0 / scn.imu_rate_hz
    # specific force of the latest IMU interval at each sample (sample 0: first interval)
    dvel = u_true[:, nav.layout.U_DVEL_B_SLICE]
    f_b = np.vstack([dvel[:1], dvel]) / dt

    elements = scenario_elements(scn)
    needed = needed_constellations(scn)
    notes: list[str] = []
    gps_rows, gps_min = (_gps_rows(scn, nav, elements["gps"], t_imu, x_true, f_b, notes)
                         if "gps" in needed else ([], 0))
    doppler_rate, doppler, ofdm, sl_min = (_starlink_rows(scn, nav, elements["starlink"], t_imu, x_true, f_b, notes)
                                 if "starlink" in needed else ([], [], [], 0))
    n_max = max(scn.starlink["counts"])
    if "starlink" in needed and sl_min < n_max:
        raise UserInputError(
            f"{scn.source}: [starlink] counts asks for up to {n_max} satellites but only "
            f"{sl_min} are above the {math.degrees(scn.starlink['elevation_mask_rad']):.0f} deg "
            f"mask at some Starlink epoch of this scenario; lower the counts or the mask"
        )
    if "gps" in needed and gps_min < 4:
        raise UserInputError(
            f"{scn.source}: only {gps_min} GPS satellites above the mask at some epoch (need >= 4)"
        )
    series = {name: _series(nav, name, rows, x_true, f_b) for name, rows in (
        ("pseudorange", gps_rows), ("doppler_rate", doppler_rate), ("doppler", doppler), ("ofdm_range_diff", ofdm))}
    return Setup(scn, params, t_imu, x_true, u_true, series, {"gps": gps_min, "starlink": sl_min},
                 prior_covariance(scn, profile, nav.layout), profile, notes)


# ---- one trial ----------------------------------------------------------------------------

def noise_sigma(scn: Scenario, kind_name: str) -> float:
    return {
        "pseudorange": scn.gps["pseudorange_sigma_m"],
        "doppler_rate": scn.starlink["doppler_rate_sigma_hz_s"],
        "doppler": scn.starlink["doppler_sigma_hz"],
        "ofdm_range_diff": scn.starlink["ofdm_sigma_m"],
    }[kind_name]


def selected_rows(setup: Setup, kind_name: str, count: int) -> np.ndarray:
    """Rows of a series used by a mode with `count` Starlink satellites (GPS: all, minus outages)."""
    s = setup.series[kind_name]
    if kind_name == "pseudorange":
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
    x_true: np.ndarray   # (n+1, NX) truth including this trial's biases, clock and LO
    params: np.ndarray | None = None   # the filter's parameters (realism compensation), else the setup's


def trial_records(setup: Setup, mode: str, count: int, rng: np.random.Generator,
                  nav: navfuncs.NavFunctions | None = None, noise_free: bool = False) -> Trial:
    """Draw one trial of `mode` with `count` Starlink satellites.

    The random draws are made in a fixed order for every mode and count, so trials with
    the same seed share IMU, clock and noise realisations (common random numbers).
    noise_free: no sensor noise, no biases, filter starts at the truth (used for the PCRB
    and for checks).
    """
    nav = nav or navfuncs.NavFunctions(params=setup.params)
    scn, L, prof = setup.scn, nav.layout, setup.imu_profile
    n = setup.u_true.shape[0]
    dt = 1.0 / scn.imu_rate_hz
    x_true = setup.x_true.copy()
    g = 0.0 if noise_free else 1.0

    b_a, b_g = bias_walks(rng, prof, n, dt, g)
    q_cdt, q_cddt = setup.params[L.P_Q_CDT], setup.params[L.P_Q_CDDT]
    c_ddt = _random_walk(rng, n, dt, scn.gps["clock_drift_mps"], g * q_cddt)
    c_dt = scn.gps["clock_bias_m"] + np.concatenate([[0.0], np.cumsum(c_ddt[:-1] * dt)]) \
        + _random_walk(rng, n, dt, 0.0, g * q_cdt)
    b_lo = _random_walk(rng, n, dt, scn.starlink["lo_offset_hz"], g * setup.params[L.P_Q_BLO])
    x_true[:, L.X_B_A_SLICE] = b_a
    x_true[:, L.X_B_G_SLICE] = b_g
    x_true[:, L.X_C_DT], x_true[:, L.X_C_DDT], x_true[:, L.X_B_LO] = c_dt, c_ddt, b_lo

    u = measured_increments(rng, prof, setup.u_true, b_a, b_g, dt, g)
    imu = ImuTable(setup.t_imu[1:], np.full(n, dt), u)
    parts = []   # [kind_name, rows, z, sigma]
    for kind_name in SERIES:
        s = setup.series[kind_name]
        sigma = noise_sigma(scn, kind_name)
        noise = rng.standard_normal(s.t_s.size)  # drawn for every series: common numbers
        if kind_name not in MODE_OBSERVABLES[mode]:
            continue
        rows = selected_rows(setup, kind_name, count)
        k = np.rint(s.t_s[rows] * scn.imu_rate_hz).astype(int)
        # clock and LO states enter linearly: z = h(truth at zero) + H . (their true values)
        z = s.z_true[rows].copy()
        for off, dx_off in ((L.X_C_DT, L.DX_DC_DT), (L.X_C_DDT, L.DX_DC_DDT), (L.X_B_LO, L.DX_DB_LO)):
            z += s.H[rows, dx_off] * x_true[k, off]
        z += g * sigma * noise[rows]
        parts.append([kind_name, rows, z, sigma])

    # the initial error is drawn over the states with a prior (not states a scenario leaves at
    # zero), so adding an uncoupled state to the layout leaves every draw unchanged
    live = np.flatnonzero(np.diag(setup.P0) > 0)
    dx0 = np.zeros(L.NDX)
    if not noise_free:
        dx0[live] = rng.multivariate_normal(np.zeros(live.size), setup.P0[np.ix_(live, live)])
    x0 = nav.boxplus(x_true[0], dx0)
    params = setup.params
    if not noise_free and realism.active(scn):   # truth != filter; draws after all of the above
        u, params = realism.apply(setup, nav, rng, u, parts)
        imu = ImuTable(setup.t_imu[1:], np.full(n, dt), u)
    tables = [_table(kind_name, setup.series[kind_name], rows, z, sigma) for kind_name, rows, z, sigma in parts]
    # the road every source takes: tables -> records (aux f_b averaged from these IMU increments)
    inputs = assemble(imu, params, Prior(x0, setup.P0), satellites=tables, nav=nav,
                      orbit_consider=None if noise_free else realism.orbit_consider(scn))
    return Trial(inputs.merged(), x0, x_true, params)


def _table(kind_name: str, s: SatSeries, rows: np.ndarray, z: np.ndarray, sigma: float):
    """The measurements of `rows` of a series as the road's satellite table of that kind."""
    return SATELLITE_TABLES[kind_name](s.t_s[rows], s.sat_id[rows], z, sigma, s.sat_ecef[rows],
                                       None if kind_name == "pseudorange" else s.ref_ecef[rows])
