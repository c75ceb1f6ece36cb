"""Generic nominal trajectories of each motion class with their satellites (package doc)."""
from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field
from typing import Sequence

import casadi as ca
import numpy as np

from leonav.codegen.observability.settings import (DT_S, GNSS_OBSERVABLES, GNSS_RADIUS_M, LEO_RADIUS_M,
                                                  MIN_ELEVATION_RAD, MOTIONS, N_SATS, N_STEPS, PHASE_INTERVAL_S, SEED,
                                                  UNIT_SCALES, analysis_params)
from leonav.codegen.observability.symbolic import Symbolic, symbolic
from leonav.models import state as S
from leonav.models.constants import WGS84_GM_M3PS2

# --- generic trajectories ----------------------------------------------------------------

@dataclass
class Trajectory:
    """A nominal trajectory of the filter's model and its satellites.

    t_s (N+1,), x (N+1, NX) states at the steps, u (N, NU) increments of step k -> k+1,
    dt_s, params (NP,), measurements: list of (step, observable suffix, aux (NAUX,), sat index).
    """

    motion: str
    t_s: np.ndarray
    x: np.ndarray
    u: np.ndarray
    dt_s: float
    params: np.ndarray
    measurements: list = field(default_factory=list)


def _motion_targets(motion: str, rng: np.random.Generator, t: np.ndarray):
    """(v_enu (n, 3) m/s, euler (n, 3) rad) of a generic member of the motion class at times t."""
    n = t.size
    yaw0 = rng.uniform(-math.pi, math.pi)
    roll0, pitch0 = rng.uniform(-0.03, 0.03, size=2)  # generic but near level: readable null directions
    speed = rng.uniform(5.0, 15.0)
    if motion == "static":
        return np.zeros((n, 3)), np.tile([roll0, pitch0, yaw0], (n, 1))
    if motion == "constant-velocity":
        v = speed * np.array([math.cos(yaw0), math.sin(yaw0), 0.0])
        return np.tile(v, (n, 1)), np.tile([roll0, pitch0, yaw0], (n, 1))
    if motion == "constant-turn":
        rate = rng.choice([-1.0, 1.0]) * math.radians(rng.uniform(2.0, 5.0))
        heading = yaw0 + rate * t
        v = speed * np.c_[np.cos(heading), np.sin(heading), np.zeros(n)]
        bank = math.atan(speed * rate / 9.8)  # coordinated turn
        return v, np.c_[np.full(n, bank), np.full(n, pitch0), heading]
    if motion == "accelerating":
        rate = rng.choice([-1.0, 1.0]) * math.radians(rng.uniform(1.0, 3.0))
        acc, climb_acc = rng.uniform(0.3, 1.0), rng.uniform(0.05, 0.2)
        heading = yaw0 + rate * t
        s = speed + acc * t
        vz = 0.5 + climb_acc * t
        v = np.c_[s * np.cos(heading), s * np.sin(heading), vz]
        pitch = np.arctan2(vz, s)
        bank = np.arctan(s * rate / 9.8)
        return v, np.c_[bank, pitch, heading]
    raise ValueError(f"unknown motion class {motion!r}; expected one of {sorted(MOTIONS)}")


def _extra_states(rng: np.random.Generator) -> np.ndarray:
    """Nominal state with every block other than position, velocity and attitude at a random
    non-zero value of a few units (UNIT_SCALES): a generic point for biases, clock and LO."""
    x = np.zeros(S.NX)
    kinematic = {"p_enu", "v_enu", "q_nb"}
    for b in S.X_BLOCKS:
        if b.name not in kinematic:
            x[b.slice] = 3.0 * UNIT_SCALES.get(b.unit, 1.0) * rng.standard_normal(b.size)
    return x


def _solve_increments(sym: Symbolic, x, x_target, dt, p, guess) -> np.ndarray:
    """IMU increments taking x to the velocity and attitude of x_target in dt (Newton on mech)."""
    u = np.array(guess, dtype=float)
    for _ in range(20):
        r, J = (np.array(v) for v in sym.invert(x, u, x_target, dt, p))
        r = r.ravel()
        if np.max(np.abs(r)) < 1e-13:
            return u
        u = u - np.linalg.solve(J, r)
    r = np.array(sym.invert(x, u, x_target, dt, p)[0]).ravel()
    if np.max(np.abs(r)) > 1e-11:
        raise RuntimeError(f"IMU increments for the motion did not converge (residual {np.max(np.abs(r)):.1e})")
    return u


def _satellites(rng: np.random.Generator, r_site: np.ndarray, C_n_e: np.ndarray, radius_m: float, count: int):
    """Circular orbits of `count` satellites visible from r_site at t = 0, in random geometry.

    Returns a function t -> (r, v, a) arrays (count, 3) ECEF (Earth rotation ignored: the
    geometry only has to be generic, not a real constellation).
    """
    n_mean = math.sqrt(WGS84_GM_M3PS2 / radius_m**3)
    e1s, e2s = [], []
    for _ in range(count):
        az = rng.uniform(0, 2 * math.pi)
        el = rng.uniform(MIN_ELEVATION_RAD, math.radians(85.0))
        los = C_n_e @ np.array([math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)])
        b = r_site @ los
        rho = -b + math.sqrt(b * b - (r_site @ r_site - radius_m**2))
        r0 = r_site + rho * los
        e1 = r0 / np.linalg.norm(r0)
        w = rng.standard_normal(3)
        e2 = w - (w @ e1) * e1
        e1s.append(e1)
        e2s.append(e2 / np.linalg.norm(e2))
    e1s, e2s = np.array(e1s), np.array(e2s)

    def at(t: float):
        c, s = math.cos(n_mean * t), math.sin(n_mean * t)
        r = radius_m * (c * e1s + s * e2s)
        v = radius_m * n_mean * (-s * e1s + c * e2s)
        return r, v, -(n_mean**2) * r

    return at


def _stream(*keys) -> np.random.Generator:
    """A random stream keyed by integers and names (names hashed with CRC-32: stable across runs)."""
    return np.random.default_rng([k if isinstance(k, int) else zlib.crc32(str(k).encode()) for k in keys])


def trajectory(motion: str, observables: Sequence[str], seed: int = SEED, draw: int = 0, n_steps: int = N_STEPS,
               dt_s: float = DT_S, n_sats: int = N_SATS, sym: Symbolic | None = None) -> Trajectory:
    """A generic nominal trajectory of `motion` with measurements of `observables` at every step.

    The motion is drawn from the stream (seed, motion, draw), the satellites of a constellation
    (GNSS for `GNSS_OBSERVABLES`, LEO otherwise) from (seed, motion, draw, constellation): every
    mode sees the same motion and the same satellites of a constellation (common random numbers).
    Satellite observables (those whose model reads the aux satellite block) use `n_sats`
    satellites; differenced ones (reading the aux reference block) use satellite 0 as the
    reference and the others as measurements. Observables that do not read the satellite block
    (position fixes) give one row per step.
    """
    sym = sym or symbolic()
    rng = _stream(seed, motion, draw)
    p = analysis_params()
    t = np.arange(n_steps + 1) * dt_s
    v, euler = _motion_targets(motion, rng, t)
    x = np.empty((n_steps + 1, S.NX))
    x0 = _extra_states(rng)
    x0[S.X["p_enu"].slice] = rng.uniform(-100.0, 100.0, size=3)
    x0[S.X["v_enu"].slice] = v[0]
    x0[S.X["q_nb"].slice] = np.array(sym.q_from_euler(euler[0])).ravel()
    x[0] = x0
    targets = x.copy()
    targets[:, S.X["v_enu"].slice] = v
    targets[:, S.X["q_nb"].slice] = np.array([np.array(sym.q_from_euler(e)).ravel() for e in euler])
    u = np.zeros((n_steps, S.NU))
    guess = np.zeros(S.NU)
    guess[S.U["dvel_b"].slice] = [0.0, 0.0, 9.8 * dt_s]
    for k in range(n_steps):
        u[k] = guess = _solve_increments(sym, x[k], targets[k + 1], dt_s, p, guess)
        x[k + 1] = np.array(sym.mech(x[k], u[k], dt_s, p)).ravel()
    traj = Trajectory(motion, t, x, u, dt_s, p)

    r_site = np.array(sym.receiver(x[0], p)[0]).ravel()
    C = np.array(sym.c_n_e(p))
    f_b = np.vstack([u[:1], u])[:, S.U["dvel_b"].slice] / dt_s  # specific force of the latest interval
    for suffix in observables:
        if not _depends_on(sym, suffix, S.AUX["r_S_ecef"].slice):
            for k in range(n_steps + 1):
                aux = np.zeros(S.NAUX)
                aux[S.AUX["f_b"].slice] = f_b[k]
                traj.measurements.append((k, suffix, aux, -1))
            continue
        constellation = "gnss" if suffix in GNSS_OBSERVABLES else "leo"
        radius = GNSS_RADIUS_M if constellation == "gnss" else LEO_RADIUS_M
        sats = _satellites(_stream(seed, motion, draw, constellation), r_site, C, radius, n_sats)
        uses_ref = _depends_on(sym, suffix, S.AUX["r_ref_ecef"].slice)
        # a time difference (carrier phase) spans one tracker epoch before each step
        span = PHASE_INTERVAL_S if _depends_on(sym, suffix, S.AUX["dt_phase"].slice) else 0.0
        for k in range(n_steps + 1):
            r, vs, a = sats(t[k])
            r_prev = sats(t[k] - span)[0] if span else None
            for j in range(1 if uses_ref else 0, n_sats):
                aux = np.zeros(S.NAUX)
                aux[S.AUX["r_S_ecef"].slice], aux[S.AUX["v_S_ecef"].slice] = r[j], vs[j]
                aux[S.AUX["a_S_ecef"].slice] = a[j]
                aux[S.AUX["r_ref_ecef"].slice], aux[S.AUX["v_ref_ecef"].slice] = r[0], vs[0]
                aux[S.AUX["a_ref_ecef"].slice] = a[0]
                aux[S.AUX["f_b"].slice] = f_b[k]
                if span:
                    aux[S.AUX["dt_phase"].slice], aux[S.AUX["r_S_prev_ecef"].slice] = span, r_prev[j]
                traj.measurements.append((k, suffix, aux, j))
    return traj


def _depends_on(sym: Symbolic, suffix: str, aux_slice: slice) -> bool:
    """Whether observable `suffix`'s model reads the given aux entries (structural dependency)."""
    fn = sym.meas[suffix]
    aux = ca.SX.sym("aux", S.NAUX)
    h = fn(ca.SX.sym("x", S.NX), aux, ca.SX.sym("p", S.NP))
    return bool(ca.depends_on(h, aux[aux_slice]))
