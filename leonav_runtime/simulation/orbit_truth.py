"""The ephemeris error's truth: each satellite's true orbit against the one its elements give.

Every satellite's true orbit is offset from its element orbit by a constant radial /
along-track / cross-track error per satellite and trial (realism.py's module doc): the
along-track part is a time shift of the state, the rest shift the position. Here: the error
draws, the moved satellite states, the change they make in each measurement (through the
generated model) and the spread one sigma of them causes; realism.py turns them into a trial's
truth and the filter's compensation, base_station.py into a base station's corrections.
"""
from __future__ import annotations

import numpy as np

from leonav_runtime.core import model
from leonav_runtime.inputs.consider import rac_axes
from leonav_runtime.inputs.measurements import aux_blocks


def starlink_sigma_rac(eph: dict) -> np.ndarray:
    """Starlink radial, along, cross 1-sigma (m) at the configured element age."""
    age = max(eph["element_age_days"], 1.0 / 24.0)   # an element set is at least an hour old in use
    return np.asarray(eph["starlink_sigma_rac_m"]) * (age / eph["reference_age_days"]) ** eph["growth_exponent"]


def sigma_rac(eph: dict, constellation: str) -> np.ndarray:
    return starlink_sigma_rac(eph) if constellation == "starlink" else np.asarray(eph["gps_sigma_rac_m"])


def perturb_states(state9: np.ndarray, d_rac: np.ndarray) -> np.ndarray:
    """True satellite states (n, 9) [r v a] (m, m/s, m/s^2, ECEF) from the element states and
    radial/along/cross offsets d_rac (n, 3) m: along-track as a time shift, the rest as offsets."""
    r, v, a = state9[:, 0:3], state9[:, 3:6], state9[:, 6:9]
    axes = rac_axes(state9)
    dt = (d_rac[:, 1] / np.einsum("ni,ni->n", v, axes[:, 1]))[:, None]   # s along the velocity
    out = state9.copy()
    out[:, 0:3] = r + v * dt + 0.5 * a * dt**2 + d_rac[:, :1] * axes[:, 0] + d_rac[:, 2:] * axes[:, 2]
    out[:, 3:6] = v + a * dt
    return out


def draw_orbit_errors(rng: np.random.Generator, setup) -> dict[str, dict[int, np.ndarray]]:
    """Per constellation, per NORAD id: radial/along/cross offsets (m) of this trial. Every
    satellite of the run gets one, in id order, whatever the mode (common random numbers)."""
    eph, out = setup.scn.realism["ephemeris"], {}
    for constellation in ("gps", "starlink"):
        kinds = [o.suffix for o in model.OBSERVABLES if o.table == "satellite" and o.constellation == constellation]
        ids = np.unique(np.concatenate([setup.series[k].sat_id for k in kinds]))
        d = rng.standard_normal((ids.size, 3)) * sigma_rac(eph, constellation)
        out[constellation] = dict(zip(ids.tolist(), d))
    return out


def ref_ids(setup, kind_name: str, rows: np.ndarray) -> np.ndarray:
    """NORAD id of each row's reference satellite: the rank-0 satellite of its epoch, taken
    from a series of the same constellation that is not differenced, which holds every ranked
    satellite of every epoch (a differenced series has no rank-0 rows of its own)."""
    c = model.observable(kind_name).constellation
    ref = setup.series[next(o.suffix for o in model.OBSERVABLES
                            if o.table == "satellite" and o.constellation == c and not o.reads_ref)]
    top = ref.rank == 0
    by_t = dict(zip(ref.t_s[top].tolist(), ref.sat_id[top].tolist()))
    return np.array([by_t[t] for t in setup.series[kind_name].t_s[rows].tolist()], dtype=np.int64)


def offsets(errors: dict[int, np.ndarray], ids: np.ndarray) -> np.ndarray:
    return np.array([errors[i] for i in ids.tolist()]).reshape(-1, 3)


def _model(setup, nav, kind_name: str, rows: np.ndarray, aux: np.ndarray) -> np.ndarray:
    k = np.rint(setup.series[kind_name].t_s[rows] * setup.scn.imu_rate_hz).astype(int)
    h, _ = nav.h_many(kind_name, setup.x_true[k], aux, params=setup.params, jacobian=False)
    return h


def moved_states(s, rows: np.ndarray, d_sat: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """The satellite states (n, 9) of a series' rows moved by radial/along/cross offsets d_sat
    (n, 3) m, and for a time difference its start position (n, 3) moved along the same orbit
    (None for any other observable)."""
    sat9 = perturb_states(s.sat_ecef[rows], d_sat)
    if s.sat_prev_r_m is None:
        return sat9, None
    return sat9, moved_start(s.sat_prev_r_m[rows], s.sat_ecef[rows], s.interval_s[rows], d_sat)


def moved_start(prev_r: np.ndarray, sat9: np.ndarray, interval_s: np.ndarray, d_sat: np.ndarray) -> np.ndarray:
    """A time difference's start positions (n, 3) m, ECEF, moved by the offsets d_sat (n, 3) of its
    end along the same orbit: the start's velocity taken back over the interval (s) with the end's
    acceleration (sat9 (n, 9): the end's [r v a] on the element orbit)."""
    v, a = sat9[:, 3:6], sat9[:, 6:9]
    prev = np.concatenate([prev_r, v - a * np.asarray(interval_s)[:, None], a], axis=1)
    return perturb_states(prev, d_sat)[:, 0:3]


def move_aux(aux: np.ndarray, d_sat: np.ndarray, layout) -> np.ndarray:
    """Aux rows (n, NAUX) of satellite records with their satellite moved by radial/along/cross
    offsets d_sat (n, 3) m (`perturb_states`); a time difference's start (aux `dt_phase` > 0)
    moves along the same orbit, so both ends carry the one offset. From the records alone: what
    a bound or a filter that estimates the offsets differentiates."""
    sat_block, _, _ = aux_blocks(layout)
    out = aux.copy()
    sat9 = aux[:, sat_block]
    out[:, sat_block] = perturb_states(sat9, d_sat)
    T = aux[:, layout.AUX_DT_PHASE]
    spans = np.flatnonzero(T > 0)
    if spans.size:
        out[spans, layout.AUX_R_S_PREV_ECEF_SLICE] = moved_start(aux[spans, layout.AUX_R_S_PREV_ECEF_SLICE],
                                                                 sat9[spans], T[spans], d_sat[spans])
    return out


def moved_aux(setup, kind_name: str, rows: np.ndarray, d_sat: np.ndarray, d_ref: np.ndarray | None,
               layout) -> np.ndarray:
    s = setup.series[kind_name]
    sat_block, ref_block, _ = aux_blocks(layout)
    aux = s.aux[rows].copy()
    aux[:, sat_block], prev = moved_states(s, rows, d_sat)
    if prev is not None:
        aux[:, layout.AUX_R_S_PREV_ECEF_SLICE] = prev
    if d_ref is not None:
        aux[:, ref_block] = perturb_states(s.ref_ecef[rows], d_ref)
    return aux


def ephemeris_delta(setup, nav, kind_name: str, rows: np.ndarray, errors: dict,
                    x_at: np.ndarray | None = None) -> np.ndarray:
    """Change (measurement unit) of each row's noise-free value when its satellite (and its
    reference) fly their true orbits instead of the element orbits; x_at (NX,): evaluated for
    a receiver at this state instead of the truth (a base station)."""
    s, constellation = setup.series[kind_name], model.observable(kind_name).constellation
    d_sat = offsets(errors[constellation], s.sat_id[rows])
    d_ref = offsets(errors[constellation], ref_ids(setup, kind_name, rows)) if s.has_ref else None
    aux = moved_aux(setup, kind_name, rows, d_sat, d_ref, nav.layout)
    if x_at is None:
        return _model(setup, nav, kind_name, rows, aux) - s.model_at_truth[rows]
    moved, _ = nav.h_many(kind_name, x_at, aux, params=setup.params, jacobian=False)
    element, _ = nav.h_many(kind_name, x_at, s.aux[rows], params=setup.params, jacobian=False)
    return moved - element


def ephemeris_sigma(setup, nav, kind_name: str, rows: np.ndarray, x_base: np.ndarray | None = None) -> np.ndarray:
    """1-sigma (measurement unit) the orbit error adds to each row: the model's change with
    the satellite (and, independently, the reference) moved one sigma along each axis; with
    x_base (NX,), what is left after a base station at that state corrects it (the change at
    the receiver minus the change at the base)."""
    s = setup.series[kind_name]
    sig = sigma_rac(setup.scn.realism["ephemeris"], model.observable(kind_name).constellation)
    base = s.model_at_truth[rows]
    at_base = None if x_base is None else nav.h_many(kind_name, x_base, s.aux[rows], params=setup.params,
                                                     jacobian=False)[0]
    var = np.zeros(rows.size)
    for moved in (("sat", "ref") if s.has_ref else ("sat",)):
        for axis in range(3):
            d = np.zeros((rows.size, 3))
            d[:, axis] = sig[axis]
            zero = np.zeros_like(d)
            aux = moved_aux(setup, kind_name, rows, d if moved == "sat" else zero,
                             (d if moved == "ref" else zero) if s.has_ref else None, nav.layout)
            change = _model(setup, nav, kind_name, rows, aux) - base
            if x_base is not None:
                change -= nav.h_many(kind_name, x_base, aux, params=setup.params, jacobian=False)[0] - at_base
            var += change**2
    return np.sqrt(var)


def base_state(setup) -> np.ndarray:
    """The base station's state (NX,): at rest at its `[base]` offset from the site."""
    x_base = setup.x_true[0].copy()
    x_base[0:3] = setup.scn.realism["base"]["offset_enu_m"]
    x_base[3:6] = 0.0
    return x_base
