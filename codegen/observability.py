"""Structural observability of the error-state filter, from the filter's own symbolic models.

For every mode (a set of observables) and motion class this module builds the discrete-time
local observability matrix of the error-state system along a trajectory of that class,

    O = [H_0; H_1 Phi_0; H_2 Phi_1 Phi_0; ...],   Phi_k = F(x_k, u_k),

with F the error-state transition and H the measurement Jacobians obtained, exactly as for
the generated filter, by differentiating the CasADi models (`models.ekf.nav_transition`,
`models.ekf.nav_h` over `models.measurements.models()`). Row block k stacks one row per
satellite and observable of the mode at step k. O is the Jacobian of the noise-free
measurement sequence h_k(f^k(x_0 [+] dx)) with respect to the initial error dx at 0 (the
discrete counterpart of the Lie-derivative test; `lie_check` verifies this identity by
forward AD through the composed nominal model).

Why discrete time: the models give the filter's mechanization as a one-step map (`mech`),
not a continuous vector field, and the filter propagates its error state with that map's
Jacobian F. Building O from the same F and H means the analysis sees exactly what the
filter sees (including the Earth rate, Coriolis and the gravity model).

The trajectory of each motion class is a generic point: random initial attitude, speed,
heading, turn rate and acceleration (seeded), random non-zero biases, clock and LO offset,
and several satellites in random visible geometry on circular orbits (GNSS orbit radius for
the pseudorange, LEO radius otherwise). IMU increments that realise the motion are solved
for on the generated mechanization itself (Newton on `mech`, as the simulator does), so the
nominal trajectory is exactly a trajectory of the filter's model.

Numerical rank: columns are scaled by a physical unit per state unit (`UNIT_SCALES`), rows by
a nominal noise per observable unit (`NOISE_SCALES`); the rank counts singular values above
`REL_TOL` times the largest, and the decision is reported with its gap (ratio of the smallest
kept to the largest dropped singular value; `MIN_GAP` is required). Null-space directions
are reported as named combinations of error-state components (names from
`models.state.DX_BLOCKS`), in physical units.

The list of error states, their units and the observables are read from `models.state` and
`models.measurements.models()`, and the rows each observable contributes from the aux
entries its model reads, so a new state block, observable or mode needs no change here. Only
what defines a motion or a satellite names a block: position, velocity and attitude of the
nominal state, the aux satellite / reference / specific-force blocks, and `GNSS_OBSERVABLES`
(the observables whose satellites are put on GNSS rather than LEO orbits). The numeric,
run-along analysis (Gramian along a scenario) is `leonav_runtime.observability`; the command
is `leonav observability`.
"""
from __future__ import annotations

import math
import time
import zlib
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import casadi as ca
import numpy as np

from leonav_runtime import observability as _rt  # naming and mode list (numeric side, no casadi)
from leonav.models import ekf, frames, kinematics
from leonav.models import state as S
from leonav.models.constants import WGS84_A_M, WGS84_GM_M3PS2
from leonav.models.measurements import models as measurement_models
from leonav.models.measurements.geometry import receiver_ecef
from leonav_runtime.core.params import build_params

# --- scaling and thresholds ----------------------------------------------------------------

UNIT_SCALES: dict[str, float] = {
    "m": 1.0,          # position, clock bias
    "m/s": 0.1,        # velocity, clock drift
    "rad": 1e-3,       # attitude (0.06 deg)
    "m/s^2": 1e-3,     # accelerometer bias (~100 ug)
    "rad/s": 1e-5,     # gyro bias (~2 deg/h)
    "Hz": 1.0,         # LO offset
}
"""Column scale per state unit: one 'typical error' of that unit. A unit not listed scales by 1."""

NOISE_SCALES: dict[str, float] = {"m": 1.0, "m/s": 0.1, "Hz/s": 1.0, "Hz": 1.0}
"""Row scale (nominal 1-sigma noise) per observable unit. A unit not listed scales by 1."""

REL_TOL = 1e-14
"""Rank threshold: a singular value of the scaled O counts when above REL_TOL * the largest.

The double-precision floor of O (roundoff in F, H and the products) is ~1e-16.5 of the largest
singular value at rest and up to 1e-15 in motion (measured over many generic draws), so
REL_TOL sits a decade above it."""
WEAK_TOL = 3e-10
"""A counted direction with a singular value below WEAK_TOL * the largest is flagged *weak*:
observable only through terms ~1e10 times smaller than the best-observed direction (the Earth
rate, the change of gravity's direction along the track). Such a direction carries no useful
information over the window (its sigma is reported)."""
MIN_GAP = 10.0
"""The rank decision is reported 'clear' when sigma_r / sigma_{r+1} >= MIN_GAP."""
TERM_TOL = _rt.TERM_TOL
"""Null-direction terms smaller than this (scaled coordinates, leading term 1) are not named."""

DT_S = 1.0           # analysis step: one IMU interval of the filter's model (s)
N_STEPS = 30         # steps along the motion (measurements at steps 0..N_STEPS)
N_SATS = 6           # satellites per satellite observable (generic geometry)
SEED = 20260223
SITE = (math.radians(43.0848638), math.radians(-77.6786127), 170.0)  # the paper's site (rad, rad, m)
GNSS_OBSERVABLES = tuple(m.suffix for m in S.MEASUREMENTS if m.source == "gnss")
"""Observables whose satellites are on GNSS orbits (registry source gnss); every other: LEO."""
GNSS_RADIUS_M = 26_560e3
LEO_RADIUS_M = WGS84_A_M + 550e3
MIN_ELEVATION_RAD = math.radians(20.0)

MOTIONS: dict[str, str] = {
    "static": "at rest, constant attitude",
    "constant-velocity": "straight and level at constant speed and attitude",
    "constant-turn": "level turn at constant speed and turn rate (banked)",
    "accelerating": "speeding up while climbing and turning (acceleration changes direction)",
}
"""Motion classes: name -> description."""


# --- names -------------------------------------------------------------------------------

@dataclass(frozen=True)
class Component:
    """One scalar component of the error state: name, block, index in dx, unit, scale."""

    name: str
    block: str
    index: int
    unit: str
    scale: float
    label: str   # name plus a hint, e.g. "dtheta_z (yaw)"


def components() -> list[Component]:
    """Scalar error-state components, in dx order, named from `models.state.DX_BLOCKS` by the
    naming rule of `leonav_runtime.observability.component_names` (e/n/u for ENU 3-vectors, x/y/z
    otherwise, roll/pitch/yaw hints on a rotation vector), scaled by `UNIT_SCALES`."""
    blocks = [_rt.BlockInfo(b.name, b.offset, b.size, b.unit, b.doc) for b in S.DX_BLOCKS]
    names = iter(_rt.component_names(blocks))
    out = []
    for b in S.DX_BLOCKS:
        for i in range(b.size):
            name, label = next(names)
            out.append(Component(name, b.name, b.offset + i, b.unit, UNIT_SCALES.get(b.unit, 1.0), label))
    return out


def observable_units() -> dict[str, str]:
    """Observable function suffix -> unit, from `models.state.MEASUREMENTS`."""
    return {m.suffix: m.unit for m in S.MEASUREMENTS}


def position_fix_observables() -> tuple[str, ...]:
    """The GNSS position-fix observables of `models.state.MEASUREMENTS` (suffix pos_*)."""
    return tuple(m.suffix for m in S.MEASUREMENTS if m.suffix.startswith("pos_"))


def default_modes() -> dict[str, tuple[str, ...]]:
    """The filter's modes (`leonav_runtime.scenarios.load.MODE_OBSERVABLES`) plus a GNSS position-fix mode."""
    return _rt.analysis_modes()


# --- symbolic functions ------------------------------------------------------------------

class Symbolic:
    """The CasADi functions the analysis evaluates, built once from the models (see `symbolic()`).

    step(x, u, dt, p) -> (x_next, F): the filter's nominal step and error-state transition;
    h[suffix](x, aux, p) -> H (1 x NDX); invert(x, u, x_target, dt, p) -> (r, dr/du): velocity
    and attitude residual of mech towards a target; q_from_euler; receiver(x, p) -> (r, v) ECEF;
    mech(x, u, dt, p) -> x_next; boxplus(x, dx); meas[suffix](x, aux, p) -> h.
    """

    def __init__(self, extra_observables: Mapping[str, Callable] | None = None) -> None:
        t0 = time.perf_counter()
        x, u, dt, p = ca.SX.sym("x", S.NX), ca.SX.sym("u", S.NU), ca.SX.sym("dt"), ca.SX.sym("p", S.NP)
        aux, xt, dx = ca.SX.sym("aux", S.NAUX), ca.SX.sym("x_target", S.NX), ca.SX.sym("dx", S.NDX)
        x_next, F, _ = ekf.nav_transition(x, u, dt, p)
        self.step = ca.Function("obs_step", [x, u, dt, p], [x_next, F], ["x", "u", "dt", "p"], ["x_next", "F"])
        models = dict(measurement_models())
        models.update(extra_observables or {})
        self.models = models
        self.h, self.meas = {}, {}
        for suffix, h in models.items():
            h_pred, H = ekf.nav_h(h, x, aux, p)
            self.h[suffix] = ca.Function(f"obs_H_{suffix}", [x, aux, p], [ca.densify(H)], ["x", "aux", "p"], ["H"])
            self.meas[suffix] = ca.Function(f"obs_h_{suffix}", [x, aux, p], [h_pred], ["x", "aux", "p"], ["h"])
        mech = kinematics.mech(x, u, dt, p)
        self.mech = ca.Function("obs_mech", [x, u, dt, p], [mech], ["x", "u", "dt", "p"], ["x_next"])
        dv, dth = S.DX["dv"].slice, S.DX["dtheta"].slice
        err = frames.boxminus(mech, xt)
        r = ca.vertcat(err[dv], err[dth])
        self.invert = ca.Function("obs_invert", [x, u, xt, dt, p], [r, ca.jacobian(r, u)])
        rpy = ca.SX.sym("rpy", 3)
        self.q_from_euler = ca.Function("obs_q", [rpy], [frames.quat_from_euler(rpy)])
        C = kinematics.origin(p)[4]
        self.receiver = ca.Function("obs_rx", [x, p], list(receiver_ecef(x, p)))
        self.boxplus = ca.Function("obs_boxplus", [x, dx], [frames.boxplus(x, dx)])
        self.c_n_e = ca.Function("obs_cne", [p], [C])
        self.build_s = time.perf_counter() - t0


_SYMBOLIC: Symbolic | None = None


def symbolic() -> Symbolic:
    """The process-wide `Symbolic` of the models as they are (built on first use)."""
    global _SYMBOLIC
    if _SYMBOLIC is None:
        _SYMBOLIC = Symbolic()
    return _SYMBOLIC


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
    p = np.array(build_params(*SITE))
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
        for k in range(n_steps + 1):
            r, vs, a = sats(t[k])
            for j in range(1 if uses_ref else 0, n_sats):
                aux = np.zeros(S.NAUX)
                aux[S.AUX["r_S_ecef"].slice], aux[S.AUX["v_S_ecef"].slice] = r[j], vs[j]
                aux[S.AUX["a_S_ecef"].slice] = a[j]
                aux[S.AUX["r_ref_ecef"].slice], aux[S.AUX["v_ref_ecef"].slice] = r[0], vs[0]
                aux[S.AUX["a_ref_ecef"].slice] = a[0]
                aux[S.AUX["f_b"].slice] = f_b[k]
                traj.measurements.append((k, suffix, aux, j))
    return traj


def _depends_on(sym: Symbolic, suffix: str, aux_slice: slice) -> bool:
    """Whether observable `suffix`'s model reads the given aux entries (structural dependency)."""
    fn = sym.meas[suffix]
    aux = ca.SX.sym("aux", S.NAUX)
    h = fn(ca.SX.sym("x", S.NX), aux, ca.SX.sym("p", S.NP))
    return bool(ca.depends_on(h, aux[aux_slice]))


# --- the observability matrix ------------------------------------------------------------

def transitions(traj: Trajectory, sym: Symbolic | None = None) -> np.ndarray:
    """F_k (N, NDX, NDX) along the trajectory: one mapped call of the generated step."""
    sym = sym or symbolic()
    n = traj.u.shape[0]
    step = sym.step.map(n)
    _, F = step(traj.x[:-1].T, traj.u.T, traj.dt_s, traj.params)
    return np.array(F).reshape(S.NDX, n, S.NDX).transpose(1, 0, 2)


def measurement_rows(traj: Trajectory, sym: Symbolic | None = None):
    """(steps (m,), suffixes (m,), H (m, NDX)) of every measurement of the trajectory, one mapped
    call per observable."""
    sym = sym or symbolic()
    steps = np.array([m[0] for m in traj.measurements], dtype=int)
    suffixes = np.array([m[1] for m in traj.measurements], dtype=object)
    H = np.zeros((steps.size, S.NDX))
    for suffix in dict.fromkeys(suffixes):
        rows = np.flatnonzero(suffixes == suffix)
        aux = np.array([traj.measurements[i][2] for i in rows]).T
        fn = sym.h[suffix].map(rows.size)
        H[rows] = np.array(fn(traj.x[steps[rows]].T, aux, traj.params)).reshape(rows.size, S.NDX)
    return steps, suffixes, H


def observability_matrix(traj: Trajectory, sym: Symbolic | None = None):
    """(O (m, NDX), steps (m,), suffixes (m,), Phi (N+1, NDX, NDX)): O row i = H_i Phi_{step_i},
    Phi_k = F_{k-1} ... F_0 (Phi_0 = I), unscaled (rows per observable unit, columns per dx unit)."""
    F = transitions(traj, sym)
    Phi = np.empty((F.shape[0] + 1, S.NDX, S.NDX))
    Phi[0] = np.eye(S.NDX)
    for k in range(F.shape[0]):
        Phi[k + 1] = F[k] @ Phi[k]
    steps, suffixes, H = measurement_rows(traj, sym)
    O = np.einsum("mi,mij->mj", H, Phi[steps])
    return O, steps, suffixes, Phi


def column_scales() -> np.ndarray:
    """Physical unit of every dx component (UNIT_SCALES by the block's unit)."""
    return np.array([c.scale for c in components()])


def row_scales(suffixes: Sequence[str]) -> np.ndarray:
    """Nominal noise of every row (NOISE_SCALES by the observable's unit)."""
    units = observable_units()
    return np.array([NOISE_SCALES.get(units.get(s, ""), 1.0) for s in suffixes])


@dataclass
class RankDecision:
    """Numerical rank of a scaled matrix.

    sv_rel: singular values (descending, all n) relative to the largest, sv_max; rank: count
    above REL_TOL; n_weak: counted ones below WEAK_TOL; gap: sigma_r / sigma_{r+1} (inf when
    full rank or when the dropped values are exact zeros); clear: gap >= MIN_GAP; V: right
    singular vectors (columns, descending order).
    """

    sv_rel: np.ndarray
    sv_max: float
    rank: int
    n_weak: int
    gap: float
    clear: bool
    V: np.ndarray

    @property
    def null_space(self) -> np.ndarray:
        """(n, n - rank) orthonormal basis of the numerical null space (scaled coordinates)."""
        return self.V[:, self.rank:]

    @property
    def weak_space(self) -> np.ndarray:
        """(n, n_weak) the weakly observable directions (scaled coordinates), weakest last."""
        return self.V[:, self.rank - self.n_weak:self.rank]


def rank_decision(A: np.ndarray, rel_tol: float = REL_TOL, weak_tol: float = WEAK_TOL,
                  min_gap: float = MIN_GAP) -> RankDecision:
    """SVD rank of A with the relative threshold rel_tol, the weak flag and the gap check."""
    n = A.shape[1]
    if A.shape[0] == 0 or not np.any(A):
        return RankDecision(np.zeros(n), 0.0, 0, 0, math.inf, True, np.eye(n))
    _, sv, Vt = np.linalg.svd(A, full_matrices=A.shape[0] < n)  # V complete (n x n) either way
    sv_full = np.zeros(n)
    sv_full[: sv.size] = sv
    smax = float(sv_full[0])
    rel = sv_full / smax
    rank = int(np.sum(rel > rel_tol))
    n_weak = int(np.sum((rel > rel_tol) & (rel <= weak_tol)))
    gap = math.inf if rank == n or rel[rank] == 0 else float(rel[rank - 1] / rel[rank])
    return RankDecision(rel, smax, rank, n_weak, gap, gap >= min_gap, Vt.T)


def rank_only(A: np.ndarray, rel_tol: float = REL_TOL) -> int:
    """The rank of `rank_decision` without the singular vectors."""
    if A.shape[0] == 0 or not np.any(A):
        return 0
    sv = np.linalg.svd(A, compute_uv=False)
    return int(np.sum(sv > rel_tol * sv[0]))


# --- naming (one implementation, shared with the run-along analysis) ------------------------

def naming(comps: Sequence[Component] | None = None) -> _rt.Naming:
    """Names, labels, units and unit scales of the components, for `name_directions`."""
    comps = list(comps or components())
    return _rt.Naming(tuple(c.name for c in comps), tuple(c.label for c in comps), tuple(c.unit for c in comps),
                      np.array([c.scale for c in comps]))


def name_directions(N: np.ndarray, comps: Sequence[Component] | None = None, term_tol: float = TERM_TOL) -> list[dict]:
    """Named canonical basis of span(N) (scaled coordinates): `leonav_runtime.observability.name_subspace`."""
    return _rt.name_subspace(N, naming(comps), term_tol)


def name_vector(v: np.ndarray, comps: Sequence[Component] | None = None, term_tol: float = 1e-2) -> dict:
    """One direction (scaled coordinates) named with its largest component leading."""
    return _rt.name_vector(v, naming(comps), term_tol)


def classify_components(N: np.ndarray, comps: Sequence[Component] | None = None,
                        zero_tol: float = 1e-12) -> dict[str, list[str]]:
    """Components that are unobservable (alone a null direction), observable (orthogonal to the
    null space, to `zero_tol` in squared projection) or not separately observable (the rest:
    they enter a null direction together with others), from the null-space basis N."""
    comps = list(comps or components())
    frac = np.sum(N**2, axis=1) if N.size else np.zeros(len(comps))
    out = {"unobservable": [], "combination": [], "observable": []}
    for c, f in zip(comps, frac):
        key = "unobservable" if f > 1 - 1e-8 else "observable" if f < zero_tol else "combination"
        out[key].append(c.name)
    return out


def observability_index(O_scaled: np.ndarray) -> np.ndarray:
    """Per component, 1 - posterior / prior variance for a prior of one unit (UNIT_SCALES) per
    component and the scaled information O^T O: 0 = no information, 1 = fully determined."""
    n = O_scaled.shape[1]
    post = np.linalg.inv(np.eye(n) + O_scaled.T @ O_scaled)
    return 1.0 - np.diag(post)


# --- the analysis ------------------------------------------------------------------------

@dataclass
class CaseResult:
    """Observability of one mode under one motion class (see `analyze_case`).

    O is unscaled (rows per observable unit, columns per dx unit); O_scaled = O / row_scale *
    column_scales(); Phi (N+1, NDX, NDX) the error-state transitions from step 0.
    """

    mode: str
    motion: str
    observables: tuple[str, ...]
    decision: RankDecision
    rank_by_step: list[int]
    steps_to_saturate: int
    draw_ranks: list[tuple[int, int]]
    null_directions: list[dict]
    weak_directions: list[dict]
    weakest: dict
    classes: dict[str, list[str]]
    index: np.ndarray
    seconds: float
    trajectory: Trajectory
    O: np.ndarray
    O_scaled: np.ndarray
    Phi: np.ndarray
    row_scale: np.ndarray

    @property
    def rank(self) -> int:
        return self.decision.rank

    @property
    def draws_agree(self) -> bool:
        """Every generic draw gave the same rank."""
        return len({r for r, _ in self.draw_ranks}) == 1

    @property
    def null_space_physical(self) -> np.ndarray:
        """(NDX, d) null directions in physical units (columns scaled back by the units)."""
        return column_scales()[:, None] * self.decision.null_space

    def summary(self) -> dict:
        """JSON-ready summary (no large arrays but the singular values)."""
        d = self.decision
        comps = components()
        return {
            "mode": self.mode, "motion": self.motion, "observables": list(self.observables),
            "n_states": S.NDX, "rank": d.rank, "weak": d.n_weak, "nullity": S.NDX - d.rank,
            "gap": d.gap, "gap_clear": d.clear, "rank_by_step": self.rank_by_step,
            "steps_to_saturate": self.steps_to_saturate, "draws_agree": self.draws_agree,
            "draw_ranks": [list(r) for r in self.draw_ranks],
            "singular_values_rel": d.sv_rel, "singular_value_max": d.sv_max,
            "unobservable_directions": self.null_directions,
            "weak_directions": self.weak_directions,
            "weakest_observable": self.weakest,
            "unobservable_components": self.classes["unobservable"],
            "combination_components": self.classes["combination"],
            "observable_components": self.classes["observable"],
            "observability_index": {c.name: float(v) for c, v in zip(comps, self.index)},
            "seconds": self.seconds,
        }


def analyze_case(mode: str, observables: Sequence[str], motion: str, seed: int = SEED, n_steps: int = N_STEPS,
                 dt_s: float = DT_S, n_sats: int = N_SATS, n_draws: int = 2,
                 sym: Symbolic | None = None) -> CaseResult:
    """Observability of `observables` (+ IMU) under `motion` at `n_draws` generic points.

    Draw i is `trajectory(motion, observables, seed, i)`. The first draw is reported; the others
    must give the same rank (`draws_agree`, ranks and weak counts in `draw_ranks`).
    """
    t0 = time.perf_counter()
    sym = sym or symbolic()
    comps = components()
    col = column_scales()
    draws, first = [], None
    for draw in range(n_draws):
        traj = trajectory(motion, observables, seed, draw, n_steps, dt_s, n_sats, sym)
        O, steps, suffixes, Phi = observability_matrix(traj, sym)
        rs = row_scales(suffixes)
        Os = O / rs[:, None] * col[None, :]
        dec = rank_decision(Os)
        draws.append((dec.rank, dec.n_weak))
        if first is None:
            first = (traj, O, steps, Os, dec, Phi, rs)
    traj, O, steps, Os, dec, Phi, rs = first
    by_step = [rank_only(Os[steps <= k]) for k in range(n_steps + 1)]
    saturate = next(k for k, r in enumerate(by_step) if r == by_step[-1]) + 1  # measurement epochs
    sv_abs = dec.sv_rel * dec.sv_max

    def described(i: int) -> dict:
        """Direction i of V with its sigma: in scaled units, and in the leading component's unit
        (the sigma of that component along this direction, all others following it)."""
        d = name_vector(dec.V[:, i], comps)
        v = dec.V[:, i]
        lead = int(np.argmax(np.abs(v)))
        sigma_units = float(1.0 / sv_abs[i])
        return {"sv_rel": float(dec.sv_rel[i]), "sigma_units": sigma_units,
                "sigma": sigma_units * abs(v[lead]) * comps[lead].scale, "sigma_unit": comps[lead].unit, **d}

    weak = [described(i) for i in range(dec.rank - dec.n_weak, dec.rank)]
    weakest = described(dec.rank - 1) if dec.rank > 0 else {}
    return CaseResult(mode, motion, tuple(observables), dec, by_step, saturate, draws,
                      name_directions(dec.null_space, comps), weak, weakest,
                      classify_components(dec.null_space, comps), observability_index(Os),
                      time.perf_counter() - t0, traj, O, Os, Phi, rs)


def analyze(modes: Mapping[str, Sequence[str]] | None = None, motions: Sequence[str] | None = None,
            seed: int = SEED, n_steps: int = N_STEPS, dt_s: float = DT_S, n_sats: int = N_SATS,
            n_draws: int = 2, progress: Callable[[CaseResult], None] | None = None) -> dict:
    """Structural observability of every mode x motion class.

    modes: {mode name: observable suffixes} (default `default_modes()`); motions: names of
    `MOTIONS` (default all). Returns {"cases": [CaseResult], "build_s", "seconds", "settings"}.
    """
    t0 = time.perf_counter()
    modes = dict(modes or default_modes())
    motions = list(motions or MOTIONS)
    for m in motions:
        if m not in MOTIONS:
            raise ValueError(f"unknown motion class {m!r}; expected one of {', '.join(MOTIONS)}")
    sym = symbolic()
    for mode, obs in modes.items():
        bad = [o for o in obs if o not in sym.h]
        if bad:
            raise ValueError(f"mode {mode!r}: unknown observable(s) {bad}; known: {sorted(sym.h)}")
    cases = []
    for mode, obs in modes.items():
        for motion in motions:
            case = analyze_case(mode, obs, motion, seed, n_steps, dt_s, n_sats, n_draws, sym)
            cases.append(case)
            if progress:
                progress(case)
    return {"cases": cases, "build_s": sym.build_s, "seconds": time.perf_counter() - t0,
            "settings": settings(seed, n_steps, dt_s, n_sats, n_draws)}


def settings(seed: int = SEED, n_steps: int = N_STEPS, dt_s: float = DT_S, n_sats: int = N_SATS,
             n_draws: int = 2) -> dict:
    """The analysis settings and thresholds, for the record."""
    return {
        "method": "discrete-time local observability matrix O = [H_0; H_1 Phi_0; H_2 Phi_1 Phi_0; ...] of the "
                  "error state along a generic trajectory of each motion class; F and H by CasADi AD of models/ "
                  "as generated for the filter; SVD of O with rows / nominal noise and columns * unit scale",
        "seed": seed, "n_steps": n_steps, "dt_s": dt_s, "n_sats": n_sats, "n_draws": n_draws,
        "rel_tol": REL_TOL, "weak_tol": WEAK_TOL, "min_gap": MIN_GAP,
        "unit_scales": UNIT_SCALES, "noise_scales": NOISE_SCALES,
        "site_lat_lon_h": [math.degrees(SITE[0]), math.degrees(SITE[1]), SITE[2]],
        "motions": MOTIONS, "components": [c.name for c in components()],
    }


# --- the Lie-derivative identity ------------------------------------------------------------

def composed_measurements(traj: Trajectory, sym: Symbolic | None = None) -> ca.Function:
    """y(dx0): every measurement of the trajectory as a function of the initial error dx0,
    through the nominal models only: x_0 = x0 [+] dx0, x_{k+1} = mech(x_k, u_k), y_i = h_i(x_{step_i}).

    Built as an MX graph (one `mapaccum` of mech over the steps, one mapped h per observable),
    so its size does not grow with the number of steps. Its Jacobian at dx0 = 0 is O.
    """
    sym = sym or symbolic()
    n = traj.u.shape[0]
    dx0 = ca.MX.sym("dx0", S.NDX)
    x0 = sym.boxplus(ca.DM(traj.x[0]), dx0)
    roll = sym.mech.mapaccum("obs_roll", n)  # accumulates x over the steps
    X = ca.horzcat(x0, roll(x0, ca.DM(traj.u.T), traj.dt_s, ca.DM(traj.params)))
    steps = [m[0] for m in traj.measurements]
    suffixes = [m[1] for m in traj.measurements]
    ys = []
    order = []
    for suffix in dict.fromkeys(suffixes):
        rows = [i for i, s in enumerate(suffixes) if s == suffix]
        aux = ca.DM(np.array([traj.measurements[i][2] for i in rows]).T)
        Xs = ca.horzcat(*[X[:, steps[i]] for i in rows])
        ys.append(sym.meas[suffix].map(len(rows))(Xs, aux, ca.DM(traj.params)).T)
        order += rows
    y = ca.vertcat(*ys)
    perm = np.argsort(order)
    return ca.Function("obs_sequence", [dx0], [y[perm.tolist()]], ["dx0"], ["y"])


def lie_check(traj: Trajectory, O: np.ndarray, rng: np.random.Generator, n_dirs: int = 3,
              sym: Symbolic | None = None) -> float:
    """Largest relative difference between O v and the directional derivative (`jtimes`) of the
    composed measurement sequence at dx0 = 0, over `n_dirs` random directions v."""
    seq = composed_measurements(traj, sym)
    dx0 = ca.MX.sym("dx0", S.NDX)
    v = ca.MX.sym("v", S.NDX)
    jv = ca.Function("obs_jtimes", [dx0, v], [ca.jtimes(seq(dx0), dx0, v)])
    worst = 0.0
    for _ in range(n_dirs):
        d = rng.standard_normal(S.NDX) * column_scales()
        got = np.array(jv(np.zeros(S.NDX), d)).ravel()
        want = O @ d
        worst = max(worst, float(np.max(np.abs(got - want)) / max(np.max(np.abs(want)), 1e-300)))
    return worst
