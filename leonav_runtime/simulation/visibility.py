"""Which satellites a scenario sees: its element sets (kept per process) and, per epoch,
the visible satellites ranked by the selection rule, with their SGP4 states."""
from __future__ import annotations

import math

import numpy as np

from leonav_runtime.orbits import geometry
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.orbits import ElementSet, default_elements, group_by_constellation, load_elements, propagate_ecef
from leonav_runtime.orbits.propagate import warn_if_stale
from leonav_runtime.scenarios.load import Scenario, mode_of


def needed_constellations(scn: Scenario) -> tuple[str, ...]:
    """Constellations the scenario's modes use (each satellite observable names its own)."""
    used = {c for m in scn.modes for c in mode_of(m).constellations}
    return tuple(c for c in ("gps", "starlink") if c in used)


def scenario_elements(scn: Scenario) -> dict[str, ElementSet]:
    """Element sets of the scenario: built-in Walker constellations at its epoch, or its files.

    Files must give every constellation the scenario's modes use (`needed_constellations`).
    Kept per process for the same epoch / files (studies prepare many cells on one epoch;
    generating the built-in shells is most of a 20 s scenario's preparation).
    """
    stats = [(str(p), p.stat().st_mtime_ns, p.stat().st_size) if p.is_file() else (str(p),)
             for p in scn.element_files]
    key = (scn.element_source, scn.epoch_utc.isoformat(), tuple(stats))
    if key not in _ELEMENTS:
        _ELEMENTS.clear()   # one element set per process at a time: bounded memory
        _ELEMENTS[key] = _load_scenario_elements(scn)
    out = _ELEMENTS[key]
    for need in needed_constellations(scn):
        if need not in out:
            raise UserInputError(
                f"{scn.source}: [elements] files give no {need} element sets "
                f"(found: {', '.join(sorted(out)) or 'none'})"
            )
    return out


_ELEMENTS: dict[tuple, dict[str, ElementSet]] = {}


def _load_scenario_elements(scn: Scenario) -> dict[str, ElementSet]:
    if scn.element_source == "builtin":
        return default_elements(scn.epoch_utc)
    return group_by_constellation([load_elements(path) for path in scn.element_files])



def _receiver_ecef(scn: Scenario, p_enu: np.ndarray) -> np.ndarray:
    r0 = geometry.geodetic_to_ecef(scn.lat_rad, scn.lon_rad, scn.alt_m)
    return geometry.enu_to_ecef(p_enu, r0, scn.lat_rad, scn.lon_rad)


def _candidates(scn, es, t_s, p_enu, mask_rad) -> np.ndarray:
    """Satellites that can be above the mask during t_s: within CANDIDATE_MARGIN_RAD of it on
    a grid of at most CANDIDATE_STEP_S (or that SGP4 cannot propagate, reported later)."""
    step = max(1, int(CANDIDATE_STEP_S / max(float(np.min(np.diff(t_s))), 1e-9)))
    j = np.unique(np.append(np.arange(0, t_s.size, step), t_s.size - 1))
    coarse = propagate_ecef(es, scn.epoch_utc, t_s[j], acceleration=False, warn_stale=False)
    _, el, _ = geometry.az_el_range(coarse.r_ecef_m, _receiver_ecef(scn, p_enu[j])[None, :, :], scn.lat_rad,
                                    scn.lon_rad)
    keep = ~np.all(np.isfinite(el), axis=1) | (np.nanmax(np.where(np.isfinite(el), el, -np.inf), axis=1)
                                               >= mask_rad - CANDIDATE_MARGIN_RAD)
    return np.flatnonzero(keep)


# A LEO satellite's elevation changes by < 1 deg/s (550 km, overhead): 2.5 s either side of a
# grid point moves it < 2.5 deg, well inside the 10 deg margin. Only satellites that can be
# visible are propagated at every epoch (same states, ranks and ids: SGP4 is per satellite).
CANDIDATE_STEP_S, CANDIDATE_MARGIN_RAD = 5.0, math.radians(10.0)


def _visible_ranked(scn, es, t_s, p_enu, mask_rad, notes: list[str], acceleration=True, priority=None):
    """States of the satellites of `es` that can be visible at t_s and, per epoch, the visible
    ones sorted by elevation (or, given `priority` (one number per satellite of `es`), by
    descending priority: the `random` rule). Returns (states, ranked, rho, es_used): indices
    in `ranked` and rows of `states` refer to `es_used`, the candidate subset of `es`.

    Satellites SGP4 cannot propagate are left out (NaN) and named in `notes`.
    """
    warn_if_stale(es, scn.epoch_utc, t_s)  # over the whole set the user gave, not the candidates
    if t_s.size > 2:
        cand = _candidates(scn, es, t_s, p_enu, mask_rad)
        es = es.select(cand)
        priority = None if priority is None else priority[cand]
    states = propagate_ecef(es, scn.epoch_utc, t_s, acceleration=acceleration, warn_stale=False)
    for name, norad, reason in states.failures:
        notes.append(f"{es.constellation} {name} ({norad}) left out: {reason}")
    r_rx = _receiver_ecef(scn, p_enu)                         # (nt, 3)
    _, el, rho = geometry.az_el_range(states.r_ecef_m, r_rx[None, :, :], scn.lat_rad, scn.lon_rad)
    el = np.where(np.isfinite(el), el, -np.inf)
    ranked = []
    for j in range(t_s.size):
        vis = np.flatnonzero(el[:, j] >= mask_rad)
        key = el[vis, j] if priority is None else priority[vis]
        ranked.append(vis[np.argsort(-key, kind="stable")])
    return states, ranked, rho, es
