"""Names of error-state components and of null-space directions (from the generated layout)."""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Sequence

import numpy as np

from leonav_runtime.core import compiled, model

GNSS_FIX_MODE = "fix+imu"
REL_TOL = 1e-12
"""A singular value of A(t) counts towards the rank when above REL_TOL * the largest. Looser
than the structural analysis' 1e-14 (codegen.observability.REL_TOL): a run multiplies thousands
of transitions, and the roundoff floor of the paper's 20 s static run reaches 1e-13.8."""
VAGUE = 1e6
"""sigma_info uses a vague prior of VAGUE units per component (units: S, by default prior sigmas)."""

_AXES_ENU, _AXES_BODY = ("e", "n", "u"), ("x", "y", "z")
_ROTATION_NAMES = ("roll", "pitch", "yaw")



# --- names ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class BlockInfo:
    """One error-state block: name, offset, size, unit and description."""

    name: str
    offset: int
    size: int
    unit: str
    doc: str


def component_names(blocks: Sequence[BlockInfo]) -> list[tuple[str, str]]:
    """(name, label) of every scalar component of the error-state blocks, in order.

    The one naming rule of both analyses: a 3-vector block gets suffixes e/n/u when its doc says
    ENU, else x/y/z; a 3-vector in rad (a rotation vector) gets the hints roll/pitch/yaw; other
    sizes are numbered.
    """
    out = []
    for b in blocks:
        if b.size == 1:
            out.append((b.name, b.name))
            continue
        axes = (_AXES_ENU if "ENU" in b.doc else _AXES_BODY) if b.size == 3 else tuple(map(str, range(b.size)))
        for i, a in enumerate(axes):
            name = f"{b.name}_{a}"
            hint = b.unit == "rad" and b.size == 3
            out.append((name, f"{name} ({_ROTATION_NAMES[i]})" if hint else name))
    return out


_LAYOUT_LINE = re.compile(r"^DX_([A-Z0-9_]+) = (\d+)\s*#\s*([^:]*):\s*(.*)$")


def layout_blocks(layout: ModuleType | None = None) -> list[BlockInfo]:
    """Error-state blocks of the generated layout (gen/state_layout.py, the twin of models/state.py).

    Offsets and sizes come from the module's DX_<NAME> / DX_<NAME>_SIZE constants; unit and
    description from the generated comment of each DX_<NAME> line (empty when absent).
    """
    layout = layout or compiled.load_layout(compiled.GEN_DIR)
    notes = {}
    path = getattr(layout, "__file__", None)
    if path and Path(path).exists():
        for line in Path(path).read_text().splitlines():
            m = _LAYOUT_LINE.match(line)
            if m:
                notes[m.group(1)] = (m.group(3).strip(), m.group(4).strip())
    blocks = []
    for attr in dir(layout):
        if attr.startswith("DX_") and not attr.endswith("_SIZE") and hasattr(layout, f"{attr}_SIZE"):
            key = attr[3:]
            unit, doc = notes.get(key, ("", ""))
            blocks.append(BlockInfo(key.lower(), int(getattr(layout, attr)), int(getattr(layout, f"{attr}_SIZE")),
                                    unit, doc))
    return sorted(blocks, key=lambda b: b.offset)


def analysis_modes(layout: ModuleType | None = None) -> dict[str, tuple[str, ...]]:
    """Modes analysed (name -> observable suffixes): the paper's, GNSS position fixes
    (`GNSS_FIX_MODE`), and each local sensor of the registry added to the paper's first two
    (GNSS and LEO) modes, e.g. gps+imu+baro, leo-alpha+imu+baro."""
    names = [*model.PAPER_MODES, GNSS_FIX_MODE]
    names += [f"{base}+{token}" for token in model.LOCAL_SENSORS for base in model.PAPER_MODES[:2]]
    return {name: model.parse_mode(name).suffixes for name in names}


@dataclass(frozen=True)
class Naming:
    """How to name directions: per component name, label (name with a hint), unit and scale
    (the unit a direction's scaled coordinates are expressed in)."""

    names: tuple[str, ...]
    labels: tuple[str, ...]
    units: tuple[str, ...]
    scales: np.ndarray


MAJOR_TERM = 0.05
"""Terms with at least this share of the largest (scaled) name a direction in its short label."""
PIVOT_SHARE = 0.05
"""Canonical basis of a subspace: the leading component of each direction is the earliest one with
at least this share of the largest remaining column norm (see `name_subspace`)."""
TERM_TOL = 1e-4
"""Terms below this (scaled, leading term 1) are not listed in a direction of a canonical basis."""


def _direction(row: np.ndarray, lead: int, nm: Naming, term_tol: float) -> dict:
    """A direction (scaled coordinates, `row[lead]` = 1) as named terms in physical units."""
    order = [lead] + [i for i in np.argsort(-np.abs(row)) if i != lead and abs(row[i]) >= term_tol]
    terms = [{"component": nm.names[i], "label": nm.labels[i],
              "coefficient": float(row[i] * nm.scales[i] / nm.scales[lead]), "unit": nm.units[i],
              "scaled": float(row[i])} for i in order]
    biggest = max(abs(t["scaled"]) for t in terms)
    major = [t["label"] for t in terms if abs(t["scaled"]) >= MAJOR_TERM * biggest]
    text = " ".join((f"1 {t['unit']} {t['label']}" if k == 0 else f"{t['coefficient']:+.3g} {t['unit']} {t['label']}")
                    .replace("  ", " ") for k, t in enumerate(terms))
    return {"leading": nm.names[lead], "label": " and ".join(major), "text": text, "terms": terms}


def name_subspace(N: np.ndarray, nm: Naming, term_tol: float = TERM_TOL) -> list[dict]:
    """Named canonical basis of the subspace spanned by the columns of N (scaled coordinates).

    The basis is made readable by Gauss-Jordan elimination on N^T: each basis vector has a
    leading component (coefficient 1) absent from the others. Pivots go to the earliest
    component (dx order: navigation states before biases and clock) that carries at least
    `PIVOT_SHARE` of the largest remaining column norm, so a tilt / accelerometer-bias pair
    reads '1 rad dtheta_y (pitch) +9.8 m/s^2 db_a_x'. Each direction is returned as
    {"leading", "label" (its major terms), "text" (the combination in physical units:
    '1 rad dtheta_z (yaw) -5.3e-05 rad/s db_g_x' means 1 rad of yaw error together with
    -5.3e-05 rad/s of x gyro bias error), "terms"}.
    """
    d = N.shape[1]
    if d == 0:
        return []
    B = np.array(N.T, dtype=float)
    lead: list[int] = []
    for k in range(d):
        norms = np.linalg.norm(B[k:], axis=0)
        norms[lead] = 0.0
        j = int(np.flatnonzero(norms >= PIVOT_SHARE * norms.max())[0])
        p = k + int(np.argmax(np.abs(B[k:, j])))
        B[[k, p]] = B[[p, k]]
        B[k] /= B[k, j]
        for r in range(d):
            if r != k:
                B[r] -= B[r, j] * B[k]
        lead.append(j)
    return [_direction(B[i], lead[i], nm, term_tol) for i in np.argsort(lead)]


def name_vector(v: np.ndarray, nm: Naming, term_tol: float = 1e-2) -> dict:
    """One direction (scaled coordinates) named with its largest component leading; terms below
    `term_tol` of it are left out."""
    v = np.asarray(v, dtype=float)
    lead = int(np.argmax(np.abs(v)))
    return _direction(v / v[lead], lead, nm, term_tol)


