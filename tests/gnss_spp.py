"""Test helper: plain NumPy single-point least squares on L1 C/A pseudoranges.

Only a check of the satellite positions and clocks against RTKLIB's single-point
solution (the product's positioning goes through the generated models). It mirrors
rnx2rtkp's defaults for `-p 0` (no ionosphere/troposphere correction, elevation mask
from the current position, Sagnac term in the range, TGD applied, RTKLIB's default
variance model: 0.3^2 (1 + 1/sin el) + URA^2 + 0.3^2 + 5^2 + 3^2 m^2).
"""
from __future__ import annotations

import numpy as np

from leonav.hardware.gnss.lnav import URA_UPPER_M, ura_index
from leonav_runtime.gen.constants import C_LIGHT_MPS, GPS_OMEGA_E_RADPS
from leonav_runtime.orbits.geometry import az_el_range, ecef_to_geodetic
from leonav_runtime.gnss.sat_states import states_for_observations


def single_point(obs, eph, *, mask_deg: float = 10.0, signal: str = "1C", weighted: bool = True,
                 iterations: int = 10):
    """{t_gps_s: (r_ecef_m (3,), clock_m, n_used)} for every epoch with >= 4 satellites."""
    use = obs.signal == signal
    o = obs.take(use)
    st = states_for_observations(o, eph)
    out = {}
    for t in o.epochs():
        k = np.flatnonzero((o.t_gps_s == t) & st.ok)
        if k.size < 4:
            continue
        rs, dts, pr = st.r_ecef_m[k], st.clock_s[k], o.pseudorange_m[k]
        ura = np.array([URA_UPPER_M[min(ura_index(a), 14)] for a in eph.data["accuracy_m"][st.index[k]]])
        x = np.zeros(4)
        used = np.ones(k.size, bool)
        for _ in range(iterations):
            rr = x[:3]
            rho = np.linalg.norm(rs - rr, axis=1)
            rho += GPS_OMEGA_E_RADPS * (rs[:, 0] * rr[1] - rs[:, 1] * rr[0]) / C_LIGHT_MPS
            if np.linalg.norm(rr) > 6.0e6:
                lat, lon, _h = ecef_to_geodetic(rr)
                _az, el, _r = az_el_range(rs, rr, float(lat), float(lon))
                used = el >= np.radians(mask_deg)
                sin_el = np.sin(np.maximum(el, 1e-3))
            else:
                sin_el = np.ones(k.size)
            if used.sum() < 4:
                break
            v = pr - (rho + x[3] - C_LIGHT_MPS * dts)
            e = (rr - rs) / np.linalg.norm(rs - rr, axis=1)[:, None]
            h = np.hstack([e, np.ones((k.size, 1))])
            var = 0.09 + 0.09 / sin_el + ura**2 + 0.09 + 25.0 + 9.0 if weighted else np.ones(k.size)
            w = 1.0 / np.sqrt(var)
            dx, *_ = np.linalg.lstsq(h[used] * w[used, None], v[used] * w[used], rcond=None)
            x += dx
            if np.linalg.norm(dx) < 1e-4:
                break
        if used.sum() >= 4:
            out[float(t)] = (x[:3].copy(), float(x[3]), int(used.sum()))
    return out
