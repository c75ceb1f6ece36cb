"""Satellite ECEF states and covariance from operator ephemerides, at any time of their span.

Interpolation: per 60 s interval, a quintic Hermite polynomial through the two bounding
records' position, velocity and acceleration (EME2000). The file gives position and
velocity; the acceleration is the zonal gravity model SGP4 is built on (point mass + J2,
J3, J4, `propagate.gravity_ecef_mps2`) evaluated about the true pole. Why this choice:
  - accuracy: the truncation term is (h/2)^6 / 6! |r^(6)| ~ 1e-5 m at h = 60 s in LEO; what is
    left is the acceleration the model leaves out (drag, tesserals, ~1e-4 m/s^2) times h^2/64,
    a few mm (tests/test_operator_ephemeris.py: 2e-5 m against an orbit integrated with the
    same gravity, 2.3 mm with an unmodelled 2e-5 m/s^2). A cubic Hermite without the
    acceleration leaves (h/2)^4 / 4! n^4 r ~ 0.3 m (measured 0.34 m);
  - locality: only the two records around t are used, so a discontinuity in the file (the
    operator's "blend" products join two arcs) spoils one interval, not the 8 a Lagrange
    interpolant over 8 points would.
Covariance: the UVW (radial, in-track, cross-track) covariance is interpolated linearly
between the two records (a convex combination of two covariances is one), then rotated to
EME2000 with the axes of the interpolated state (U = r/|r|, W = r x v/|r x v|, V = W x U;
the same rotation for the position and velocity blocks) and to ECEF with the 6 x 6 map of
`eme2000.ecef_jacobian` (rotation and the Earth-rate term of the velocity).
"""
from __future__ import annotations

import datetime as _dt
import warnings
from dataclasses import dataclass

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.orbits.elements import ElementSet, as_utc
from leonav_runtime.orbits.eme2000 import (
    ecef_jacobian,
    ecef_to_eme2000,
    eme2000_to_ecef,
    eme2000_to_teme_matrix,
)
from leonav_runtime.orbits.eop import EopTable
from leonav_runtime.orbits.operator_ephemeris import (
    OperatorEphemeris,
    OperatorEphemerisSet,
)
from leonav_runtime.orbits.propagate import (
    SatStates,
    acceleration_ecef_mps2,
    earth_orientation,
    gravity_ecef_mps2,
    propagate_ecef,
)


class OperatorCoverageWarning(UserWarning):
    """Some requested satellites have no operator ephemeris, or not over the requested times."""


@dataclass
class OperatorStates:
    """ECEF states of `names` at `epoch_utc + t_s` from operator ephemerides.

    r_ecef_m, v_ecef_mps, a_ecef_mps2: (nsat, nt, 3) m, m/s, m/s^2 (ECEF/ITRF); cov_ecef:
    (nsat, nt, 6, 6) covariance of [r, v] in ECEF (m^2, m^2/s, m^2/s^2). ok: (nsat,) False for
    a satellite without a file or outside its file's span at some time (NaN rows there);
    failures: [(name, reason)]."""

    r_ecef_m: np.ndarray
    v_ecef_mps: np.ndarray
    a_ecef_mps2: np.ndarray
    cov_ecef: np.ndarray
    t_s: np.ndarray
    epoch_utc: _dt.datetime
    names: list[str]
    ok: np.ndarray
    failures: list[tuple[str, str]]


def _accel_eme2000(r_eme2000_m: np.ndarray, m_teme: np.ndarray) -> np.ndarray:
    """Zonal gravity (n, 3) at EME2000 positions (n, 3), evaluated in the true-pole frame
    (M: (n, 3, 3) EME2000 -> TEME) and rotated back."""
    r_true = np.einsum("nij,nj->ni", m_teme, r_eme2000_m)
    return np.einsum("nji,nj->ni", m_teme, gravity_ecef_mps2(r_true))


def _hermite5(s: np.ndarray, p0, d0, c0, p1, d1, c1) -> tuple[np.ndarray, np.ndarray]:
    """Quintic Hermite value and d/ds at s in [0, 1] from the end values p, first derivatives
    d and second derivatives c in s (for time t = t0 + s h: d = h v, c = h^2 a)."""
    s = s[:, None]
    s2, s3 = s * s, s * s * s
    s4, s5 = s3 * s, s3 * s2
    p = ((1 - 10 * s3 + 15 * s4 - 6 * s5) * p0 + (s - 6 * s3 + 8 * s4 - 3 * s5) * d0
         + 0.5 * (s2 - 3 * s3 + 3 * s4 - s5) * c0 + (10 * s3 - 15 * s4 + 6 * s5) * p1
         + (-4 * s3 + 7 * s4 - 3 * s5) * d1 + 0.5 * (s3 - 2 * s4 + s5) * c1)
    dp = ((-30 * s2 + 60 * s3 - 30 * s4) * p0 + (1 - 18 * s2 + 32 * s3 - 15 * s4) * d0
          + 0.5 * (2 * s - 9 * s2 + 12 * s3 - 5 * s4) * c0 + (30 * s2 - 60 * s3 + 30 * s4) * p1
          + (-12 * s2 + 28 * s3 - 15 * s4) * d1 + 0.5 * (3 * s2 - 8 * s3 + 5 * s4) * c1)
    return p, dp


def uvw_axes(r_m: np.ndarray, v_mps: np.ndarray) -> np.ndarray:
    """(n, 3, 3) Q whose columns are U (radial), V (in-track), W (cross-track) of states (n, 3)
    in their own frame: x_frame = Q x_uvw."""
    u = r_m / np.linalg.norm(r_m, axis=1, keepdims=True)
    w = np.cross(r_m, v_mps)
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    return np.stack([u, np.cross(w, u), w], axis=2)


def uvw_to_frame(cov_uvw: np.ndarray, r_m: np.ndarray, v_mps: np.ndarray) -> np.ndarray:
    """(n, 6, 6) covariance of [r, v] rotated from the UVW axes of states (n, 3) to their frame."""
    q = uvw_axes(r_m, v_mps)
    b = np.zeros((q.shape[0], 6, 6))
    b[:, 0:3, 0:3] = q
    b[:, 3:6, 3:6] = q
    return b @ cov_uvw @ np.swapaxes(b, 1, 2)


# A smooth LEO orbit at 60 s leaves ~0.01 m and ~0.2 m/s in these residuals (the first
# records of a public file 0.35 m); the operator's arc joins ("blend") hundreds of m, ~16 m/s.
SEAM_POSITION_M = 10.0
SEAM_VELOCITY_MPS = 2.0


def _seam(eph: OperatorEphemeris, k: np.ndarray, a_nodes: np.ndarray) -> np.ndarray:
    """(len(k),) True where interval k (records k, k+1) is not one smooth arc: the corrected
    trapezoid r1 - r0 - h (v0 + v1)/2 + h^2 (a1 - a0)/12 (error h^5 r^(5) / 720) or
    v1 - v0 - h (a0 + a1)/2 (h^3 a'' / 12) beyond the limits, scaled with the step."""
    h = (np.diff(eph.t_ms) * 1e-3)[k][:, None]
    r, v = eph.r_eme2000_m, eph.v_eme2000_mps
    res_r = r[k + 1] - r[k] - 0.5 * h * (v[k] + v[k + 1]) + h * h * (a_nodes[k + 1] - a_nodes[k]) / 12.0
    res_v = v[k + 1] - v[k] - 0.5 * h * (a_nodes[k] + a_nodes[k + 1])
    scale = h[:, 0] / 60.0
    return ((np.linalg.norm(res_r, axis=1) > SEAM_POSITION_M * np.maximum(1.0, scale ** 5))
            | (np.linalg.norm(res_v, axis=1) > SEAM_VELOCITY_MPS * np.maximum(1.0, scale ** 3)))


def _node_accelerations(eph: OperatorEphemeris, nodes: np.ndarray, eop: EopTable | None) -> np.ndarray:
    """(len(eph), 3) zonal gravity (m/s^2, EME2000) at the records `nodes` (zero elsewhere)."""
    t_node = eph.t_ms * 1e-3
    ut1_utc, _, _ = earth_orientation(eph.start_utc, t_node[nodes], eop=eop)
    m_teme, _ = eme2000_to_teme_matrix(eph.start_utc, t_node[nodes], ut1_utc)
    a_nodes = np.zeros((len(eph), 3))
    a_nodes[nodes] = _accel_eme2000(eph.r_eme2000_m[nodes], m_teme)
    return a_nodes


def discontinuities(eph: OperatorEphemeris, eop: EopTable | None = None) -> list[int]:
    """File line numbers of the records that start a new arc (the second record of each
    interval that is not one smooth orbit); interpolation refuses times inside those."""
    if len(eph) < 2:
        return []
    k = np.arange(len(eph) - 1)
    bad = _seam(eph, k, _node_accelerations(eph, np.arange(len(eph)), eop))
    return [5 + 4 * (int(j) + 1) for j in np.flatnonzero(bad)]


def interpolate_eme2000(eph: OperatorEphemeris, t_rel_s: np.ndarray, eop: EopTable | None = None
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(r (nt, 3) m, v (nt, 3) m/s, cov_uvw (nt, 6, 6), inside (nt,) bool) at t_rel_s seconds
    after eph.start_utc (EME2000). Times outside the records' span, or inside an interval
    that joins two arcs (`discontinuities`), are NaN, inside False."""
    t_rel_s = np.atleast_1d(np.asarray(t_rel_s, dtype=float))
    t_node = eph.t_ms * 1e-3
    nt = t_rel_s.size
    r = np.full((nt, 3), np.nan)
    v = np.full((nt, 3), np.nan)
    cov = np.full((nt, 6, 6), np.nan)
    inside = (t_rel_s >= t_node[0]) & (t_rel_s <= t_node[-1]) & (len(eph) >= 2)
    if not inside.any():
        return r, v, cov, inside
    tq = t_rel_s[inside]
    k = np.clip(np.searchsorted(t_node, tq, side="right") - 1, 0, len(eph) - 2)
    nodes = np.unique(np.concatenate([k, k + 1]))
    a_nodes = _node_accelerations(eph, nodes, eop)
    k_used, k_of = np.unique(k, return_inverse=True)
    seam = _seam(eph, k_used, a_nodes)[k_of]
    if seam.any():               # an interval across two arcs: refused (counted by the caller)
        keep = ~seam
        inside[np.flatnonzero(inside)[seam]] = False
        tq, k = tq[keep], k[keep]
        if not tq.size:
            return r, v, cov, inside
    h = np.diff(t_node)[k]
    s = (tq - t_node[k]) / h
    rr, vv = eph.r_eme2000_m, eph.v_eme2000_mps
    hh = h[:, None]
    p, dp = _hermite5(s, rr[k], vv[k] * hh, a_nodes[k] * hh * hh, rr[k + 1], vv[k + 1] * hh,
                      a_nodes[k + 1] * hh * hh)
    r[inside], v[inside] = p, dp / hh
    w = s[:, None, None]
    cov[inside] = (1.0 - w) * eph.cov_uvw[k] + w * eph.cov_uvw[k + 1]
    return r, v, cov, inside


def _span_text(eph: OperatorEphemeris) -> str:
    stop = eph.start_utc + _dt.timedelta(milliseconds=int(eph.t_ms[-1]))
    return f"{eph.start_utc:%Y-%m-%d %H:%M:%S} .. {stop:%Y-%m-%d %H:%M:%S} UTC"


def operator_states_ecef(ephemerides: OperatorEphemerisSet, names: list[str], epoch_utc: _dt.datetime,
                         t_s: np.ndarray, *, eop: EopTable | None = None) -> OperatorStates:
    """ECEF states and covariance of satellites `names` at epoch_utc + t_s (UTC seconds).

    A requested satellite without a file, or a time outside its file's span, leaves NaN rows,
    `ok` False and one reason in `failures` (announced by one OperatorCoverageWarning); when
    no requested satellite is covered at all, a `UserInputError` in one line says what the
    ephemerides hold and what was asked."""
    epoch_utc = as_utc(epoch_utc)
    t_s = np.atleast_1d(np.asarray(t_s, dtype=float))
    nsat, nt = len(names), t_s.size
    r_eme = np.full((nsat, nt, 3), np.nan)
    v_eme = np.full((nsat, nt, 3), np.nan)
    cov_eme = np.full((nsat, nt, 6, 6), np.nan)
    ok = np.zeros(nsat, bool)
    failures: list[tuple[str, str]] = []
    req_lo, req_hi = (epoch_utc + _dt.timedelta(seconds=float(t_s.min())),
                      epoch_utc + _dt.timedelta(seconds=float(t_s.max()))) if nt else (epoch_utc, epoch_utc)
    for i, name in enumerate(names):
        eph = ephemerides.ephemerides.get(name)
        if eph is None:
            failures.append((name, "no operator ephemeris file for this satellite"))
            continue
        r, v, cov_uvw, inside = interpolate_eme2000(eph, t_s - (eph.start_utc - epoch_utc).total_seconds(), eop)
        if not inside.all():
            t_rel = t_s - (eph.start_utc - epoch_utc).total_seconds()
            within = (t_rel >= eph.t_ms[0] * 1e-3) & (t_rel <= eph.t_ms[-1] * 1e-3)
            outside, seam = int((~within).sum()), int((within & ~inside).sum())
            why = []
            if outside:
                why.append(f"its ephemeris ({eph.source}) covers {_span_text(eph)}, "
                           f"{outside} of {nt} requested times lie outside it")
            if seam:
                lines = discontinuities(eph, eop)
                why.append(f"{seam} of {nt} requested times fall between two arcs of {eph.source} "
                           f"(new arc at line {', '.join(map(str, lines[:3]))})")
            failures.append((name, "; ".join(why)))
        ok[i] = inside.all()
        r_eme[i], v_eme[i] = r, v
        good = inside
        if good.any():
            cov_eme[i, good] = uvw_to_frame(cov_uvw[good], r[good], v[good])
    if nsat and not np.isfinite(r_eme[..., 0]).any():
        held = ", ".join(list(ephemerides.ephemerides)[:3]) + (" ..." if len(ephemerides.ephemerides) > 3 else "")
        spans = {_span_text(e) for e in ephemerides.ephemerides.values()}
        raise UserInputError(
            f"operator ephemerides cover none of the {nsat} requested satellites over "
            f"{req_lo:%Y-%m-%d %H:%M:%S} .. {req_hi:%Y-%m-%d %H:%M:%S} UTC (first asked: {names[0]}); "
            f"they hold {len(ephemerides.ephemerides)} satellites ({held}) over {' / '.join(sorted(spans)[:2])}")
    if failures:
        warnings.warn(f"operator ephemerides: {len(failures)} of {nsat} satellites not covered over the run "
                      f"(NaN there); first: {failures[0][0]}: {failures[0][1]}", OperatorCoverageWarning, stacklevel=2)
    r_ecef, v_ecef = eme2000_to_ecef(r_eme, v_eme, epoch_utc, t_s, eop=eop)
    T = ecef_jacobian(epoch_utc, t_s, eop=eop)
    cov_ecef = T[None] @ cov_eme @ np.swapaxes(T, 1, 2)[None]
    a_ecef = acceleration_ecef_mps2(r_ecef, v_ecef)
    return OperatorStates(r_ecef, v_ecef, a_ecef, cov_ecef, t_s, epoch_utc, list(names), ok, failures)


def operator_sat_states(ephemerides: OperatorEphemerisSet, elements: ElementSet, epoch_utc: _dt.datetime, t_s: np.ndarray,
                        *, eop: EopTable | None = None) -> tuple[SatStates, np.ndarray]:
    """In place of `propagate.propagate_ecef(elements, ...)`: the same `SatStates` (indices of
    `elements` kept), each satellite whose operator ephemeris (joined by name) covers every
    time of t_s taken from it, the others from SGP4. Returns (states, from_operator (nsat,))."""
    states = propagate_ecef(elements, epoch_utc, t_s, eop=eop)
    names = [str(n).strip() for n in elements.names]
    held = [i for i, n in enumerate(names) if n in ephemerides.ephemerides]
    use = np.zeros(len(names), bool)
    if not held:
        return states, use
    with warnings.catch_warnings():     # the satellites not covered keep SGP4; counted in the mask
        warnings.simplefilter("ignore", OperatorCoverageWarning)
        try:
            op = operator_states_ecef(ephemerides, [names[i] for i in held], epoch_utc, t_s, eop=eop)
        except UserInputError:
            return states, use
    for j, i in enumerate(held):
        if op.ok[j]:
            use[i] = True
            states.r_ecef_m[i], states.v_ecef_mps[i] = op.r_ecef_m[j], op.v_ecef_mps[j]
            if states.a_ecef_mps2 is not None:
                states.a_ecef_mps2[i] = op.a_ecef_mps2[j]
    return states, use


def ephemerides_from_elements(elements: ElementSet, epoch_utc: _dt.datetime, t_nodes_s: np.ndarray,
                              cov_uvw: np.ndarray, *, source: str = "sgp4", eop: EopTable | None = None
                              ) -> OperatorEphemerisSet:
    """Operator ephemerides of `elements`' SGP4 orbits at epoch_utc + t_nodes_s (evenly
    spaced, s), EME2000, with UVW covariance cov_uvw ((6, 6) or (n, 6, 6), SI) at every
    record: what the simulator and the fixtures write with `operator_ephemeris.write_file`."""
    t_nodes_s = np.asarray(t_nodes_s, dtype=float)
    steps = np.diff(t_nodes_s)
    if t_nodes_s.size < 2 or np.abs(steps - steps[0]).max() > 1e-3 or steps[0] <= 0:
        raise UserInputError(f"operator ephemerides: record times must be 2 or more, evenly spaced and increasing "
                             f"(got {t_nodes_s.size} times)")
    st = propagate_ecef(elements, epoch_utc, t_nodes_s, acceleration=False, warn_stale=False, eop=eop)
    start = as_utc(epoch_utc) + _dt.timedelta(seconds=float(t_nodes_s[0]))
    stop = start + _dt.timedelta(seconds=float(t_nodes_s[-1] - t_nodes_s[0]))
    t_ms = np.rint((t_nodes_s - t_nodes_s[0]) * 1000).astype(np.int64)
    cov = np.broadcast_to(np.asarray(cov_uvw, dtype=float), (t_nodes_s.size, 6, 6))
    out = {}
    for j, name in enumerate(elements.names):
        if not st.ok[j]:
            continue    # SGP4 failed: no ephemeris rather than NaN records (st.failures says why)
        r, v = ecef_to_eme2000(st.r_ecef_m[j], st.v_ecef_mps[j], epoch_utc, t_nodes_s, eop=eop)
        name = str(name).strip()
        out[name] = OperatorEphemeris(source, name, None, start, stop, float(steps[0]), source, "UVW", t_ms.copy(),
                                      r, v, cov.copy())
    return OperatorEphemerisSet(out, [(n, why) for n, _, why in st.failures])
