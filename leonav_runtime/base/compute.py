"""A base receiver's corrections from its own measurements at its known position.

For each measurement of a satellite (a `DopplerRateTable` or `DopplerTable` row whose satellite
state comes from the element set, as on the rover), the correction is

    c = z_measured - h(element-set satellite state, base at its known position, static)

with h the generated model (`NavFunctions.h_many`), evaluated for a receiver at rest at the base
position: p = 0 in ENU at the base, v = 0, level, specific force = -(normal gravity). What stays
in c is what the model does not know and a nearby rover shares: the ephemeris error's effect
(and, for the Doppler, the base's own LO offset, removed below), plus the base's noise.

- Doppler-rate: the model has no receiver-clock term; c is used as it is.
- Doppler: f_D = -(f_c/c) rho_dot + b_LO, and the base's b_LO is common to every satellite at
  an epoch. It is removed by subtracting the across-satellite mean of c at each epoch (epochs
  with fewer than 2 satellites give no Doppler correction). What that mean also removes (the
  part of the ephemeris effect common to the satellites in view) is common to the rover's
  satellites too and goes into the rover's own b_LO state. The mean jumps when a satellite
  joins or leaves: the rover's LO random walk absorbs it as a step (documented).
- Smoothing: the ephemeris part of c changes over minutes, the noise from one measurement to the
  next, so the published correction of a satellite is the inverse-variance mean of its last
  `smooth_s` seconds of c (sigma = that mean's 1-sigma), time-tagged with the newest
  measurement's time. The lag this adds (~smooth_s / 2 of a slowly varying term) is small
  against the noise it removes (docs/corrections.md).
"""
from __future__ import annotations

import collections
import math

import numpy as np

from leonav_runtime.base.protocol import Correction
from leonav_runtime.core import model, navfuncs
from leonav_runtime.inputs import filter_params, satellite_aux
from leonav_runtime.replay.timebase import filter_profile

DEFAULT_SMOOTH_S = 10.0
"""Window (s) of a satellite's corrections averaged into the published one."""


def static_receiver(origin: tuple[float, float, float], f_c_hz: float, nav: navfuncs.NavFunctions
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x (NX,), params (NP,), f_b (3,) m/s^2) of a receiver at rest at `origin` (lat rad, lon rad,
    h m), level, body axes along ENU: the state at which the base's predictions are evaluated."""
    L = nav.layout
    params = filter_params(origin, filter_profile(0.1, quantized=False), f_c_hz)
    x = np.zeros(L.NX)
    x[L.X_Q_NB_SLICE] = nav.quat_from_euler(np.zeros(3))[0]
    f_b = -nav.gravity_enu(np.zeros(3), params)       # at rest: the accelerometer reads minus gravity
    return x, params, f_b


def predicted(table, origin: tuple[float, float, float], f_c_hz: float, nav: navfuncs.NavFunctions) -> np.ndarray:
    """(n,) the table's observable predicted from its satellite states for the receiver at rest at
    `origin` (unit of the observable)."""
    x, params, f_b = static_receiver(origin, f_c_hz, nav)
    aux = satellite_aux(table, np.broadcast_to(f_b, (table.t.size, 3)), nav.layout)
    h, _ = nav.h_many(table.KIND, x, aux, params=params, jacobian=False)
    return h


def raw_corrections(table, origin, f_c_hz: float, nav: navfuncs.NavFunctions) -> tuple[np.ndarray, np.ndarray]:
    """(c (n,), sigma (n,)): measured minus predicted per row, the Doppler's per-epoch
    across-satellite mean removed (NaN where an epoch has one satellite only)."""
    z = np.asarray(table.z, float)
    c = z - predicted(table, origin, f_c_hz, nav)
    sigma = np.broadcast_to(np.asarray(table.sigma, float), z.shape).copy()
    if table.KIND == "doppler":
        epochs = np.round(np.asarray(table.t, float), 3)
        for t in np.unique(epochs):
            sel = epochs == t
            c[sel] = c[sel] - c[sel].mean() if sel.sum() >= 2 else np.nan
    return c, sigma


class CorrectionMaker:
    """Raw corrections -> published ones, per satellite smoothed over `smooth_s` (module doc)."""

    def __init__(self, smooth_s: float = DEFAULT_SMOOTH_S) -> None:
        self.smooth_s = float(smooth_s)
        self._win: dict[tuple, collections.deque] = {}

    def add(self, kind: str, norad_id: int, t_utc_s: float, c: float, sigma: float) -> Correction | None:
        """One raw correction in; the satellite's published correction at t_utc_s out (None for NaN)."""
        if not (math.isfinite(c) and math.isfinite(sigma) and sigma > 0):
            return None
        win = self._win.setdefault((kind, int(norad_id)), collections.deque())
        win.append((t_utc_s, c, sigma))
        while win and win[0][0] < t_utc_s - self.smooth_s:
            win.popleft()
        w = np.array([1.0 / s ** 2 for _, _, s in win])
        v = np.array([x for _, x, _ in win])
        return Correction(model.observable(kind).constellation, int(norad_id), kind, float(t_utc_s),
                          float(np.sum(w * v) / np.sum(w)), float(1.0 / math.sqrt(np.sum(w))))


def corrections_of_table(table, epoch_unix: float, origin, f_c_hz: float, nav: navfuncs.NavFunctions,
                         smooth_s: float = DEFAULT_SMOOTH_S) -> list[Correction]:
    """Every published correction of a whole table (t s since `epoch_unix`, UTC), in time order."""
    c, sigma = raw_corrections(table, origin, f_c_hz, nav)
    maker = CorrectionMaker(smooth_s)
    out = []
    for k in np.argsort(np.asarray(table.t, float), kind="stable"):
        corr = maker.add(table.KIND, int(table.sat_id[k]), epoch_unix + float(table.t[k]), float(c[k]),
                         float(sigma[k]))
        if corr is not None:
            out.append(corr)
    return out
