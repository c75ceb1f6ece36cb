"""The per-trial simulator as it was before the block builder (commit 97df536), kept only as the
reference the tests compare against: `trial_records` here draws one trial with the old per-trial
code (sensor-error truth, IMU noise, measurement noise, prior) and takes the input road, so
`simulate.trial_records` and `trial_block.trial_block` must give the same records bit for bit
(the same seeds, the same sweep results).

One later rule is followed here too: a block of its own stream (registry `truth.stream = own`)
is drawn only when the mode measures it; otherwise it stays at the base truth with no start
error (no other draw depends on it, so every other value is unchanged).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from leonav_runtime.core import model, navfuncs
from leonav_runtime.inputs import ImuTable, LocalSensorTable, Prior, assemble
from leonav_runtime.scenarios.load import mode_of
from leonav_runtime.simulation import realism, satellites
from leonav_runtime.simulation.sensor_errors import own_stream
from leonav_runtime.simulation.simulate import Setup, Trial, noise_sigma, satellite_table, selected_rows


def _walk(steps: np.ndarray, x0: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """x_{k+1} = phi x_k + steps_k per component, from x0: (n+1, size). phi = 1: a cumulative sum."""
    if np.all(phi == 1.0):
        return np.concatenate([[x0], x0 + np.cumsum(steps, axis=0)])
    out = np.empty((steps.shape[0] + 1, x0.size))
    out[0] = x0
    for j in range(x0.size):   # first-order recursion, per component
        out[1:, j] = lfilter([1.0], [1.0, -phi[j]], steps[:, j], zi=[phi[j] * x0[j]])[0]
    return out


def _start(block, scn, scale: float, rng: np.random.Generator, profile, layout) -> np.ndarray:
    start = block.truth["start"]
    if start == "zero":
        return np.zeros(block.size)
    if start == "prior":
        sigma = model.prior_sigmas(layout, profile, 0.0, 0.0, 0.0)[block.error_offset:block.error_offset + block.size]
        return scale * sigma * rng.standard_normal(block.size)
    section, _, key = start.partition(".")
    return np.full(block.size, float(getattr(scn, section)[key]))


def draw_truth(rng: np.random.Generator, blocks, n: int, dt: float, Phi: np.ndarray, Qd: np.ndarray, scn, profile,
               layout, scale: float = 1.0) -> dict[str, np.ndarray]:
    """Truth (n+1, size) of each block in `blocks` (registry entries, layout order) over n steps of
    dt, drawn from `rng` or each block's own stream (module doc). scale 0: no noise and no random
    start (the draws are still made, to keep the streams aligned)."""
    out: dict[str, np.ndarray] = {}
    names = {b.name for b in blocks}
    for b in blocks:
        if b.name in out or b.truth["stream"] == "none":
            continue
        r = rng if b.truth["stream"] == "trial" else own_stream(rng, b.name)
        e = slice(b.error_offset, b.error_offset + b.error_size)
        dyn = b.dynamics
        drift = model.state_block(dyn["of"]) if dyn["kind"] == "integral" else None
        if drift is not None and drift.name in names:   # an integral pair: exact two-state draw
            d = slice(drift.error_offset, drift.error_offset + drift.error_size)
            x_b0, x_d0 = _start(b, scn, scale, r, profile, layout), _start(drift, scn, scale, r, profile, layout)
            w_d = r.standard_normal((n, drift.size))
            w_b = r.standard_normal((n, b.size))
            l11 = np.sqrt(np.diag(Qd[e, e]))
            l21 = np.diag(Qd[d, e]) / np.where(l11 > 0, l11, 1.0)
            l22 = np.sqrt(np.maximum(np.diag(Qd[d, d]) - l21**2, 0.0))
            x_d = np.concatenate([[x_d0], x_d0 + np.cumsum(scale * (l21 * w_b + l22 * w_d), axis=0)])
            x_b = np.concatenate([[x_b0], x_b0 + np.cumsum(x_d[:-1] * np.diag(Phi[e, d]) + scale * l11 * w_b,
                                                            axis=0)])
            out[b.name], out[drift.name] = x_b, x_d
            continue
        x0 = _start(b, scn, scale, r, profile, layout)
        steps = r.standard_normal((n, b.size)) * (scale * np.sqrt(np.diag(Qd[e, e])))
        out[b.name] = _walk(steps, x0, np.diag(Phi[e, e]).copy())
    return out


def measured_increments(rng: np.random.Generator, profile, u_true: np.ndarray, b_a: np.ndarray,
                        b_g: np.ndarray, dt: float, scale: float = 1.0) -> np.ndarray:
    """IMU increments as the sensor gives them: the ideal ones plus the bias at the start of
    each interval and the white noise of the profile (ARW, VRW). (n, 6): rad, m/s."""
    n = u_true.shape[0]
    u = u_true.copy()
    u[:, :3] += b_g[:-1] * dt + scale * profile.arw * math.sqrt(dt) * rng.standard_normal((n, 3))
    u[:, 3:] += b_a[:-1] * dt + scale * profile.vrw * math.sqrt(dt) * rng.standard_normal((n, 3))
    return u


def _drawn(block, mode) -> bool:
    """Whether the block's truth is drawn for `mode` (module doc)."""
    read = {name for o in mode.observables for name in o.reads}
    return block.role != "navigation" and (block.truth["stream"] != "own" or block.role != "measurement"
                                           or block.error_name in read)


def _error_truth(setup: Setup, nav, rng, mode, n: int, dt: float, g: float) -> dict[str, np.ndarray]:
    """This trial's truth of every sensor-error block (sensor_errors.draw_truth)."""
    Phi, Qd = nav.sensor_error_step(dt, setup.params)
    blocks = [b for b in model.STATES if _drawn(b, mode)]
    return draw_truth(rng, blocks, n, dt, Phi, Qd, setup.scn, setup.imu_profile, nav.layout, g)


def _local_tables(setup: Setup, nav, rng, mode, x_true: np.ndarray, g: float) -> list[LocalSensorTable]:
    """The mode's local sensors: generated h at the trial's truth plus noise (each observable's own stream)."""
    L, tables = nav.layout, []
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
        tables.append(LocalSensorTable(token, setup.t_imu[k], z, sigma))
    return tables


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
    parsed = mode_of(mode)
    n = setup.u_true.shape[0]
    dt = 1.0 / scn.imu_rate_hz
    x_true = setup.x_true.copy()
    g = 0.0 if noise_free else 1.0

    errors = _error_truth(setup, nav, rng, parsed, n, dt, g)
    for name, values in errors.items():
        b = model.state_block(name)
        x_true[:, b.offset:b.offset + b.size] = values
    zero = np.zeros((n + 1, 3))
    u = measured_increments(rng, prof, setup.u_true, errors.get("b_a", zero), errors.get("b_g", zero), dt, g)
    imu = ImuTable(setup.t_imu[1:], np.full(n, dt), u)
    measuring = [b for b in model.STATES if b.role == "measurement"]
    parts = []   # [kind_name, rows, z, sigma]
    for o in satellites.satellite_observables():
        s = setup.series[o.suffix]
        sigma = noise_sigma(scn, o.suffix)
        # the paper's observables draw for every series from the trial's stream (common numbers)
        noise = (rng if o.paper else own_stream(rng, o.name)).standard_normal(s.t_s.size)
        if o not in parsed.observables:
            continue
        rows = selected_rows(setup, o.suffix, count)
        k = np.rint(s.t_s[rows] * scn.imu_rate_hz).astype(int)
        # measuring sensors' states enter linearly: z = h(truth at zero) + H . (their true values)
        z = s.z_true[rows].copy()
        for b in measuring:
            if b.error_name in o.reads:
                for j in range(b.size):
                    z += s.H[rows, b.error_offset + j] * x_true[k, b.offset + j]
        z += g * sigma * noise[rows]
        parts.append([o.suffix, rows, z, sigma])

    # the initial error is drawn over the states with a prior: the paper's blocks from the trial's
    # stream (as before any block was added), a block of its own stream from that stream
    dx0 = np.zeros(L.NDX)
    if not noise_free:
        var = np.diag(setup.P0)
        own = {b.name for b in model.STATES if b.truth["stream"] == "own"}
        shared = np.array([i for b in model.STATES if b.name not in own
                           for i in range(b.error_offset, b.error_offset + b.error_size) if var[i] > 0], int)
        dx0[shared] = rng.multivariate_normal(np.zeros(shared.size), setup.P0[np.ix_(shared, shared)])
        for b in model.STATES:
            e = slice(b.error_offset, b.error_offset + b.error_size)
            if b.name in own and _drawn(b, parsed) and np.any(var[e] > 0):
                dx0[e] = np.sqrt(var[e]) * own_stream(rng, b.name + ":prior").standard_normal(b.error_size)
    x0 = nav.boxplus(x_true[0], dx0)
    params = setup.params
    if not noise_free and realism.active(scn):   # truth != filter; draws after all of the above
        u, params, _ = realism.apply(setup, nav, rng, u, parts)
        imu = ImuTable(setup.t_imu[1:], np.full(n, dt), u)
    tables = [satellite_table(kind_name, setup.series[kind_name], rows, z, sigma)
              for kind_name, rows, z, sigma in parts]
    # the road every source takes: tables -> records (aux f_b averaged from these IMU increments)
    inputs = assemble(imu, params, Prior(x0, setup.P0), satellites=tables, nav=nav,
                      local=_local_tables(setup, nav, rng, parsed, x_true, g),
                      orbit_consider=None if noise_free else realism.orbit_consider(scn))
    return Trial(inputs.merged(parsed.streams), x0, x_true, params)
