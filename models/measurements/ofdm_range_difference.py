"""OFDM differenced one-way range (m), paper eq. 6: rho_i - rho_ref (clock-free).

rho_i = |r_S - r_U| with the aux satellite block, rho_ref with the aux ref block (ECEF).
"""
from __future__ import annotations

import casadi as ca

from leonav.models import registry as R
from leonav.models.measurements.geometry import receiver_ecef
from leonav.models.state import AUX


def h(x, aux, p):
    """Predicted range difference (m)."""
    r_U, _ = receiver_ecef(x, p)
    return ca.norm_2(aux[AUX["r_S_ecef"].slice] - r_U) - ca.norm_2(aux[AUX["r_ref_ecef"].slice] - r_U)


OBSERVABLES = (
    R.Observable("OFDM_RANGE_DIFF", "ofdm_range_diff", 9, h, "m", source="leo", token="ofdm",
                 stream="ofdm_range_diff", table="satellite", constellation="starlink", paper=True,
                 noise=R.Noise("starlink.ofdm_sigma_m", 3.0, 1e-3, 1e4, "OFDM differenced-range noise"),
                 doc="simulated OFDM differenced one-way range rho_i - rho_ref, the paper's baseline"),
)
