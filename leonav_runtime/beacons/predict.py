"""Predicted beacon Doppler and Doppler-rate of every visible satellite (static receiver).

The curves come from the generated measurement functions `leonav_h_doppler` and
`leonav_h_doppler_rate` (models/measurements/doppler.py, doppler_rate.py), evaluated at the nominal state of a static receiver at the ENU
origin (p_enu = 0, v_enu = 0, q_nb = identity, biases 0, b_lo = 0) with the specific
force that holds it still, f_b = -g_enu(0) (so the model's receiver acceleration is 0).
They are called through `leonav_runtime.core.navfuncs` (no casadi on this path).

Satellite states come from `leonav_runtime.orbits.propagate_ecef` (SGP4, ECEF, with
acceleration). Visibility uses the elevation mask at any prediction time in the window.
"""
from __future__ import annotations

import dataclasses
import datetime as _dt
import functools

import numpy as np

from leonav_runtime.beacons.spline import NotAKnotSpline
from leonav_runtime.orbits.geometry import Site
from leonav_runtime.core.navfuncs import NavFunctions
from leonav_runtime.core.params import params_array
from leonav_runtime.gen.constants import STARLINK_BEACON_HZ, STARLINK_MASK_DEG

DEFAULT_MASK_DEG = STARLINK_MASK_DEG
VISIBILITY_STEP_S = 30.0  # s, spacing of the coarse visibility samples over a capture


@functools.lru_cache(maxsize=4)
def _nav() -> NavFunctions:
    """The generated model functions (one set per process)."""
    return NavFunctions()


def _static_receiver(nav: NavFunctions, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nominal state of a receiver at rest at the ENU origin (identity attitude: body axes =
    ENU axes) and the specific force that holds it still, f_b = -g_enu(0)."""
    x = np.zeros(nav.layout.NX)
    x[nav.layout.X_Q_NB] = 1.0
    return x, -nav.gravity_enu(np.zeros(3), p)


def model_params(lat_rad: float, lon_rad: float, h_m: float, f_c_hz: float = STARLINK_BEACON_HZ) -> np.ndarray:
    """Parameter vector p for the site (WGS84 rad, rad, m) and carrier (Hz)."""
    return params_array(lat_rad, lon_rad, h_m, f_c_hz=f_c_hz)


def evaluate_model(r_ecef_m: np.ndarray, v_ecef_mps: np.ndarray, a_ecef_mps2: np.ndarray,
                   p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Doppler (Hz) and Doppler rate (Hz/s) for arrays of satellite states (..., 3), ECEF,
    from the generated `leonav_h_doppler` / `leonav_h_doppler_rate` at a static receiver."""
    shape = r_ecef_m.shape[:-1]
    n = int(np.prod(shape)) if shape else 1
    if n == 0:
        return np.zeros(shape), np.zeros(shape)
    nav = _nav()
    L = nav.layout
    x, f_b = _static_receiver(nav, p)
    aux = np.zeros((n, L.NAUX))
    aux[:, L.AUX_R_S_ECEF:L.AUX_R_S_ECEF + L.AUX_R_S_ECEF_SIZE] = np.reshape(r_ecef_m, (n, 3))
    aux[:, L.AUX_V_S_ECEF:L.AUX_V_S_ECEF + L.AUX_V_S_ECEF_SIZE] = np.reshape(v_ecef_mps, (n, 3))
    aux[:, L.AUX_A_S_ECEF:L.AUX_A_S_ECEF + L.AUX_A_S_ECEF_SIZE] = np.reshape(a_ecef_mps2, (n, 3))
    aux[:, L.AUX_F_B:L.AUX_F_B + L.AUX_F_B_SIZE] = f_b
    d = nav.h_many("doppler", x, aux, p, jacobian=False)[0]
    r = nav.h_many("doppler_rate", x, aux, p, jacobian=False)[0]
    return d.reshape(shape), r.reshape(shape)


@dataclasses.dataclass
class Predictions:
    """Curves of candidate satellites on a time grid (s since `start_utc`)."""

    start_utc: _dt.datetime
    t_s: np.ndarray            # (nt,)
    names: list[str]           # (nsat,)
    norad_ids: np.ndarray      # (nsat,)
    doppler_hz: np.ndarray     # (nsat, nt), LO offset 0
    rate_hz_s: np.ndarray      # (nsat, nt)
    elevation_rad: np.ndarray  # (nsat, nt)
    sat_index: np.ndarray      # index of each candidate in the element set
    _splines: tuple | None = dataclasses.field(default=None, init=False, repr=False, compare=False)

    def at(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Curves interpolated (cubic, not-a-knot: `spline`) at times t_s: (nsat, len(t_s)) each."""
        if self.t_s.size < 4:
            raise ValueError("prediction grid too short for interpolation")
        if self._splines is None:   # built once: every comb and iteration of the association asks
            self._splines = (NotAKnotSpline(self.t_s, self.doppler_hz), NotAKnotSpline(self.t_s, self.rate_hz_s))
        return self._splines[0](t_s), self._splines[1](t_s)


def _element_meta(elements, index: np.ndarray) -> tuple[list[str], np.ndarray]:
    names = [str(elements.names[i]) for i in index]
    ids = np.asarray([int(elements.norad_ids[i]) for i in index], int)
    return names, ids


def predict_visible(elements, site: Site, start_utc: _dt.datetime, duration_s: float,
                    step_s: float = 0.5, mask_deg: float = DEFAULT_MASK_DEG,
                    f_c_hz: float = STARLINK_BEACON_HZ, margin_s: float = 2.0) -> Predictions:
    """Predict curves of the satellites above `mask_deg` at some time in [0, duration_s].

    The grid spans [-margin_s, duration_s + margin_s] with `step_s` spacing (cubic
    interpolation of these smooth curves is accurate to well below 0.01 Hz/s at 0.5 s).
    """
    from leonav_runtime.orbits.geometry import az_el_range, geodetic_to_ecef
    from leonav_runtime.orbits import propagate_ecef

    n = int(np.ceil((duration_s + 2 * margin_s) / step_s)) + 1
    t = -margin_s + step_s * np.arange(max(n, 4))
    r_rx = np.asarray(geodetic_to_ecef(site.lat_rad, site.lon_rad, site.h_m), float)
    # coarse visibility pass over the whole set (every <= VISIBILITY_STEP_S: a pass above the
    # mask lasts minutes), then states with acceleration for the few
    t_vis = np.linspace(0.0, max(duration_s, 0.0), max(3, int(np.ceil(duration_s / VISIBILITY_STEP_S)) + 1))
    coarse = propagate_ecef(elements, start_utc, t_vis, acceleration=False)
    _, el, _ = az_el_range(coarse.r_ecef_m, r_rx, site.lat_rad, site.lon_rad)
    ok = np.asarray(coarse.ok, bool)
    vis = np.nonzero((el >= np.radians(mask_deg)).any(axis=1) & ok)[0]
    names, ids = _element_meta(elements, vis)
    if vis.size == 0:
        empty = np.zeros((0, t.size))
        return Predictions(start_utc, t, [], ids, empty, empty, empty, vis)
    st = propagate_ecef(elements.select(vis), start_utc, t, acceleration=True, warn_stale=False)  # warned above
    _, el_fine, _ = az_el_range(st.r_ecef_m, r_rx, site.lat_rad, site.lon_rad)
    p = model_params(site.lat_rad, site.lon_rad, site.h_m, f_c_hz)
    d, r = evaluate_model(st.r_ecef_m, st.v_ecef_mps, st.a_ecef_mps2, p)
    return Predictions(start_utc, t, names, ids, d, r, el_fine, vis)
