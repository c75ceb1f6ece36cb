"""OFDM differenced one-way range (m), paper eq. 6: rho_i - rho_ref (clock-free).

rho_i = |r_S - r_U| with the aux satellite block, rho_ref with the aux ref block (ECEF).
"""
from __future__ import annotations

import casadi as ca

from leonav.models.measurements.geometry import receiver_ecef
from leonav.models.state import AUX


def h(x, aux, p):
    """Predicted range difference (m)."""
    r_U, _ = receiver_ecef(x, p)
    return ca.norm_2(aux[AUX["r_S_ecef"].slice] - r_U) - ca.norm_2(aux[AUX["r_ref_ecef"].slice] - r_U)
