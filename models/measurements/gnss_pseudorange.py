"""GPS pseudorange (m): |r_S - r_U| + Sagnac + c_dt.

aux r_S_ecef is the satellite position at transmit time expressed in the ECEF frame of
the transmit epoch; the Earth's rotation during the signal flight is the Sagnac term
w_ie/c (x_S y_U - y_S x_U) (IS-GPS-200 style), so r_U is the receive-time ECEF position.
Atmospheric delays are not modelled (absorbed in R).
"""
from __future__ import annotations

import casadi as ca

from leonav.models.constants import C_LIGHT_MPS, OMEGA_IE_RADPS
from leonav.models.measurements.geometry import receiver_ecef
from leonav.models.state import AUX, X


def h(x, aux, p):
    """Predicted pseudorange (m)."""
    r_U, _ = receiver_ecef(x, p)
    r_S = aux[AUX["r_S_ecef"].slice]
    sagnac = OMEGA_IE_RADPS / C_LIGHT_MPS * (r_S[0] * r_U[1] - r_S[1] * r_U[0])
    return ca.norm_2(r_S - r_U) + sagnac + x[X["c_dt"].offset]
