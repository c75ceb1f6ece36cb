"""The analysis of every mode and motion class, and the Lie-derivative check (package doc)."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import casadi as ca
import numpy as np

from leonav.codegen.observability.matrix import (RankDecision, column_scales, observability_matrix, rank_decision,
                                                rank_only, row_scales)
from leonav.codegen.observability.names import (classify_components, components, default_modes, name_directions,
                                               name_vector, observability_index)
from leonav.codegen.observability.settings import (DT_S, MIN_GAP, MOTIONS, N_SATS, N_STEPS, NOISE_SCALES, REL_TOL,
                                                  SEED, SITE, UNIT_SCALES, WEAK_TOL)
from leonav.codegen.observability.symbolic import Symbolic, symbolic
from leonav.codegen.observability.trajectory import Trajectory, trajectory
from leonav.models import state as S

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
