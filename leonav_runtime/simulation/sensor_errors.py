"""The truth of the simulated sensor errors (IMU biases, receiver clock, LO offset, each sensor's
own bias), drawn through the generated model: every block the mechanization does not drive
follows the transition Phi and process noise Qd of `leonav_sensor_error_step` - the filter's own
dynamics of that block (registry `dynamics`), so a model change changes the truth too.

A block starts at its registry `truth.start` (a draw from its prior, zero, or a scenario key)
and draws its noise from `truth.stream`: the trial's stream in layout order (the paper's blocks:
the draws every earlier result shares; an integral pair draws its drift's noise, then its own),
or a stream of its own keyed by its name (a block added later never changes another's draws).
The realism switches (truth != model) stay in realism.py. IMU white noise: `measured_increments`.
"""
from __future__ import annotations

import math
import zlib

import numpy as np

from leonav_runtime.common.columns import columnwise
from leonav_runtime.core import model, navfuncs
from leonav_runtime.core.params import params_array


def own_stream(rng: np.random.Generator, name: str) -> np.random.Generator:
    """A stream of its own for `name`, derived from the trial's stream seed (independent of the
    draws made from the trial's stream)."""
    seq = rng.bit_generator.seed_seq
    return np.random.default_rng(np.random.SeedSequence(seq.entropy, spawn_key=(*seq.spawn_key,
                                                                                 zlib.crc32(name.encode()))))


def _walk(steps: np.ndarray, x0: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """x_{k+1} = phi x_k + steps_k per component, from x0, for B trials at once: steps (B, n, size),
    x0 (B, size) -> (B, n+1, size). phi = 1: a cumulative sum (made in `steps`)."""
    out = np.empty((steps.shape[0], steps.shape[1] + 1, x0.shape[1]))
    out[:, 0] = x0
    if np.all(phi == 1.0):
        columnwise(np.add, x0[:, None], np.cumsum(steps, axis=1, out=steps), out[:, 1:])   # steps reused
        return out
    # scipy.signal costs ~0.5 s to import (more than a paper sweep's whole report), and only a
    # first-order Gauss-Markov truth (phi < 1) needs it: the paper's random walks never do
    from scipy.signal import lfilter
    for j in range(x0.shape[1]):   # first-order recursion, per component
        out[:, 1:, j] = lfilter([1.0], [1.0, -phi[j]], steps[:, :, j], axis=1, zi=(phi[j] * x0[:, j])[:, None])[0]
    return out


def _starter(block, scn, scale: float, profile, layout):
    """The block's start as a function (stream, out) writing it into the row `out` (size,): a prior
    draw from the stream, zero, or a scenario value, its sigma or value worked out once. A block of
    trials calls it once per trial, so each trial's stream sees its start and then its noise; the
    draw goes straight into its row (a list, a stack and a product per prior start cost ~7-9 us)."""
    start = block.truth["start"]
    if start == "prior":
        sigma = model.prior_sigmas(layout, profile, 0.0, 0.0, 0.0)[block.error_offset:block.error_offset + block.size]
        factor = scale * sigma

        def prior(r: np.random.Generator, out: np.ndarray) -> None:
            r.standard_normal(out=out)
            out *= factor
        return prior
    value = 0.0
    if start != "zero":
        section, _, key = start.partition(".")
        value = float(getattr(scn, section)[key])

    def fixed(r: np.random.Generator, out: np.ndarray) -> None:
        out[:] = value
    return fixed


def draw_truth(rng: np.random.Generator, blocks, n: int, dt: float, Phi: np.ndarray, Qd: np.ndarray, scn, profile,
               layout, scale: float = 1.0) -> dict[str, np.ndarray]:
    """Truth (n+1, size) of each block in `blocks` (registry entries, layout order) over n steps of
    dt, drawn from `rng` or each block's own stream (module doc). scale 0: no noise and no random
    start (the draws are still made, to keep the streams aligned)."""
    return {k: v[0] for k, v in draw_truth_many([rng], blocks, n, dt, Phi, Qd, scn, profile, layout, scale).items()}


def draw_truth_many(rngs: list[np.random.Generator], blocks, n: int, dt: float, Phi: np.ndarray, Qd: np.ndarray,
                    scn, profile, layout, scale: float = 1.0) -> dict[str, np.ndarray]:
    """`draw_truth` for B trials at once, trial i from rngs[i]: (B, n+1, size) per block. Each
    trial's stream sees the draws of `draw_truth` in the same order, so the values are the same."""
    out: dict[str, np.ndarray] = {}
    names = {b.name for b in blocks}
    for b in blocks:
        if b.name in out or b.truth["stream"] == "none":
            continue
        rs = list(rngs) if b.truth["stream"] == "trial" else [own_stream(r, b.name) for r in rngs]
        e = slice(b.error_offset, b.error_offset + b.error_size)
        dyn = b.dynamics
        drift = model.state_block(dyn["of"]) if dyn["kind"] == "integral" else None
        if drift is not None and drift.name in names:   # an integral pair: exact two-state draw
            d = slice(drift.error_offset, drift.error_offset + drift.error_size)
            start_b, start_d = _starter(b, scn, scale, profile, layout), _starter(drift, scn, scale, profile, layout)
            x_b0, x_d0 = np.empty((len(rs), b.size)), np.empty((len(rs), drift.size))
            w_d, w_b = np.empty((len(rs), n, drift.size)), np.empty((len(rs), n, b.size))
            for i, r in enumerate(rs):   # each trial's draws in order: start, drift's start, w_d, w_b
                start_b(r, x_b0[i])
                start_d(r, x_d0[i])
                r.standard_normal(out=w_d[i])
                r.standard_normal(out=w_b[i])
            l11 = np.sqrt(np.diag(Qd[e, e]))
            l21 = np.diag(Qd[d, e]) / np.where(l11 > 0, l11, 1.0)
            l22 = np.sqrt(np.maximum(np.diag(Qd[d, d]) - l21**2, 0.0))
            x_d = np.concatenate([x_d0[:, None], x_d0[:, None] + np.cumsum(scale * (l21 * w_b + l22 * w_d), axis=1)],
                                 axis=1)
            x_b = np.concatenate([x_b0[:, None], x_b0[:, None] + np.cumsum(
                x_d[:, :-1] * np.diag(Phi[e, d]) + scale * l11 * w_b, axis=1)], axis=1)
            out[b.name], out[drift.name] = x_b, x_d
            continue
        x0, w = np.empty((len(rs), b.size)), np.empty((len(rs), n, b.size))
        start = _starter(b, scn, scale, profile, layout)
        for i, r in enumerate(rs):   # each trial's start, then its noise
            start(r, x0[i])
            r.standard_normal(out=w[i])
        columnwise(np.multiply, w, scale * np.sqrt(np.diag(Qd[e, e])), w)
        out[b.name] = _walk(w, x0, np.diag(Phi[e, e]).copy())
    return out


def error_model(nav: navfuncs.NavFunctions, dt: float, params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(Phi, Qd) of the generated sensor-error step (NDX x NDX)."""
    return nav.sensor_error_step(dt, params)


def bias_walks(rng: np.random.Generator, profile, n: int, dt: float, scale: float = 1.0,
               nav: navfuncs.NavFunctions | None = None):
    """True accelerometer and gyro biases (n+1, 3) each at the IMU samples of a profile's IMU:
    a draw from the profile's bias sigma, then their generated dynamics (m/s^2, rad/s; body)."""
    nav = nav or navfuncs.NavFunctions()
    params = params_array(0.0, 0.0, 0.0, imu=profile)
    Phi, Qd = error_model(nav, dt, params)
    imu = [b for b in model.STATES if b.role == "imu"]
    truth = draw_truth(rng, imu, n, dt, Phi, Qd, None, profile, nav.layout, scale)
    return truth["b_a"], truth["b_g"]


def measured_increments(rng: np.random.Generator, profile, u_true: np.ndarray, b_a: np.ndarray,
                        b_g: np.ndarray, dt: float, scale: float = 1.0) -> np.ndarray:
    """IMU increments as the sensor gives them: the ideal ones plus the bias at the start of
    each interval and the white noise of the profile (ARW, VRW). (n, 6): rad, m/s."""
    return measured_increments_many([rng], profile, u_true, b_a[None], b_g[None], dt, scale)[0]


def measured_increments_many(rngs: list[np.random.Generator], profile, u_true: np.ndarray, b_a: np.ndarray,
                             b_g: np.ndarray, dt: float, scale: float = 1.0) -> np.ndarray:
    """`measured_increments` of B trials at once: b_a, b_g (B, n+1, 3), trial i's noise from
    rngs[i] (gyro, then accelerometer, as `measured_increments`) -> (B, n, 6)."""
    n = u_true.shape[0]
    w_g, w_a = np.empty((len(rngs), n, 3)), np.empty((len(rngs), n, 3))
    for i, r in enumerate(rngs):
        r.standard_normal(out=w_g[i])
        r.standard_normal(out=w_a[i])
    w_g *= scale * profile.arw * math.sqrt(dt)
    w_a *= scale * profile.vrw * math.sqrt(dt)
    u = np.empty((len(rngs),) + u_true.shape)
    columnwise(np.add, u_true[:, :3], b_g[:, :-1] * dt + w_g, u[:, :, :3])
    columnwise(np.add, u_true[:, 3:], b_a[:, :-1] * dt + w_a, u[:, :, 3:])
    return u
