"""Names of the error-state components and of directions in the error space (package doc);
the naming rule is the runtime's (one implementation, shared with the run-along analysis)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from leonav.codegen.observability.settings import TERM_TOL, UNIT_SCALES
from leonav.models import state as S
from leonav_runtime import observability as _rt  # naming and mode list (numeric side, no casadi)

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
