"""The observability matrix along a trajectory, its scaling and the rank decision (package doc)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from leonav.codegen.observability.names import components, observable_units
from leonav.codegen.observability.settings import MIN_GAP, NOISE_SCALES, REL_TOL, WEAK_TOL
from leonav.codegen.observability.symbolic import Symbolic, symbolic
from leonav.codegen.observability.trajectory import Trajectory
from leonav.models import state as S

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
