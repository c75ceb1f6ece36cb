"""What the tests need of every state block, from the model registry (gen/registry.py), so that a
block added by a sensor module needs no edit here: finite-difference steps, typical random states,
a positive prior per block, and an independent NumPy reference of the documented discretization
of each block's dynamics (models/dynamics.py's docstring), to hold the generated predicts against."""
from __future__ import annotations

import math

import numpy as np

from leonav_runtime.gen import registry as REG
from leonav_runtime.gen import state_layout as L


def error_slice(block) -> slice:
    return slice(block.error_offset, block.error_offset + block.error_size)


def fd_steps() -> np.ndarray:
    """Finite-difference step per error-state component (the registry's fd_step, SI)."""
    step = np.zeros(L.NDX)
    for b in REG.STATES:
        step[error_slice(b)] = b.fd_step
    return step


def random_state(rng: np.random.Generator, scale: dict[str, float] | None = None) -> np.ndarray:
    """A random nominal state: each block ~ its typical magnitude (or `scale[name]`), unit quaternion."""
    x = np.zeros(L.NX)
    for b in REG.STATES:
        x[b.offset:b.offset + b.size] = rng.normal(size=b.size) * (scale or {}).get(b.name, b.typical)
    q = x[L.X_Q_NB_SLICE]
    x[L.X_Q_NB_SLICE] = q / np.linalg.norm(q)
    return x


def prior_sd(given: dict[str, float], profile=None) -> np.ndarray:
    """A positive 1-sigma per error component: `given[error block name]` where the test chooses,
    else the registry prior (the profile's for IMU biases), else the block's typical magnitude."""
    sd = np.zeros(L.NDX)
    for b in REG.STATES:
        if b.error_name in given:
            value = given[b.error_name]
        elif b.prior.get("profile_field") and profile is not None:
            value = getattr(profile, b.prior["profile_field"])
        else:
            value = b.prior.get("value") or b.typical
        sd[error_slice(b)] = value
    return sd


def _par(params, name: str) -> float:
    return float(params[next(q.offset for q in REG.PARAMS if q.name == name)])


def block_dynamics(dt: float, params) -> tuple[np.ndarray, np.ndarray]:
    """(Phi, Qd) of the non-navigation blocks over dt, NumPy, from each block's registry dynamics:
    random walk q dt; Gauss-Markov exp(-beta dt) and s^2 (1 - exp(-2 beta dt)) / (2 beta) (s^2 dt
    at beta 0); integral of a random walk: the exact two-state discretization."""
    Phi, Q = np.zeros((L.NDX, L.NDX)), np.zeros((L.NDX, L.NDX))
    by_name = {b.name: b for b in REG.STATES}
    drifts = {b.dynamics["of"] for b in REG.STATES if b.dynamics["kind"] == "integral"}
    for b in REG.STATES:
        d, e = b.dynamics, error_slice(b)
        eye = np.eye(b.error_size)
        if d["kind"] == "mechanization":
            continue
        if d["kind"] == "random-walk":
            Phi[e, e] = eye
            if b.name in drifts:
                continue
            q = _par(params, d["psd"]) if "psd" in d else (_par(params, d["density"]) ** 2 if "density" in d
                                                            else d["psd_value"])
            Q[e, e] = eye * q * dt
        elif d["kind"] == "gauss-markov":
            beta, s2 = _par(params, d["beta"]), _par(params, d["density"]) ** 2
            Phi[e, e] = eye * math.exp(-beta * dt)
            Q[e, e] = eye * (s2 * dt if beta == 0 else s2 * -math.expm1(-2 * beta * dt) / (2 * beta))
        elif d["kind"] == "integral":
            drift = by_name[d["of"]]
            f, qa, qb = error_slice(drift), _par(params, d["psd"]), _par(params, drift.dynamics["psd"])
            Phi[e, e], Phi[e, f] = eye, eye * dt
            Q[e, e] += eye * (qa * dt + qb * dt**3 / 3)
            Q[e, f] = Q[f, e] = eye * qb * dt**2 / 2
            Q[f, f] = eye * qb * dt
        else:   # constant
            Phi[e, e] = eye
    return Phi, Q
