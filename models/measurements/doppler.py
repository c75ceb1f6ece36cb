"""Starlink beacon Doppler (Hz): f_D = -(f_c/c) rho_dot + b_lo (beyond the paper).

b_lo is the common frequency offset of the beacon front end (LNB LO + SDR ppm) at
baseband; it is large and unknown, hence a state.
"""
from __future__ import annotations

import casadi as ca

from leonav.models import registry as R
from leonav.models.constants import C_LIGHT_MPS
from leonav.models.measurements.geometry import receiver_ecef
from leonav.models.state import AUX, P, X


def h(x, aux, p):
    """Predicted Doppler (Hz)."""
    r_U, v_U = receiver_ecef(x, p)
    r = aux[AUX["r_S_ecef"].slice] - r_U
    rho_dot = ca.dot(r / ca.norm_2(r), aux[AUX["v_S_ecef"].slice] - v_U)
    return -(p[P["f_c_hz"].offset] / C_LIGHT_MPS) * rho_dot + x[X["b_lo"].offset]


STATES = (
    R.StateBlock("b_lo", 1, "Hz", "beacon front-end frequency offset at baseband", R.RandomWalk(psd="q_blo"),
                 R.Prior(50e3, doc="LNB LO tolerance class (tens of kHz)"), fd_step=1e-3, typical=1e3,
                 truth=R.Truth("starlink.lo_offset_hz", "trial"), error_doc="LO offset error"),
)
OBSERVABLES = (
    R.Observable("DOPPLER", "doppler", 8, h, "Hz", source="leo", token="doppler", stream="doppler",
                 table="satellite", constellation="starlink", paper=True,
                 noise=R.Noise("starlink.doppler_sigma_hz", 5.0, 1e-3, 1e4, "beacon Doppler noise"),
                 doc="Starlink beacon Doppler -(f_c/c) rho_dot + b_lo (beyond the paper)"),
)
