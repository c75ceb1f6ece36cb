"""GPS pseudorange (m): |r_S - r_U| + Sagnac + c_dt.

aux r_S_ecef is the satellite position at transmit time expressed in the ECEF frame of
the transmit epoch; the Earth's rotation during the signal flight is the Sagnac term
w_ie/c (x_S y_U - y_S x_U) (IS-GPS-200 style), so r_U is the receive-time ECEF position.
Atmospheric delays are not modelled (absorbed in R).
"""
from __future__ import annotations

import casadi as ca

from leonav.models import registry as R
from leonav.models.constants import C_LIGHT_MPS, OMEGA_IE_RADPS
from leonav.models.measurements.geometry import receiver_ecef
from leonav.models.state import AUX, X

# The receiver clock: one oscillator for every constellation (GNSS_PSEUDORANGE and
# GNSS_RANGE_RATE read it too). A two-state process: the bias integrates the drift.
STATES = (
    R.StateBlock("c_dt", 1, "m", "receiver clock bias times c", R.Integral(of="c_ddt", psd="q_cdt"),
                 R.Prior(300.0, doc="1 us: a receiver clock before its first solution"), fd_step=1e-2, typical=1e3,
                 truth=R.Truth("gps.clock_bias_m", "trial"), error_doc="clock bias error"),
    R.StateBlock("c_ddt", 1, "m/s", "receiver clock drift times c", R.RandomWalk(psd="q_cddt"),
                 R.Prior(1.0, doc="a TCXO's drift class"), fd_step=1e-3, typical=10.0,
                 truth=R.Truth("gps.clock_drift_mps", "trial"), error_doc="clock drift error"),
)


def h(x, aux, p):
    """Predicted pseudorange (m)."""
    r_U, _ = receiver_ecef(x, p)
    r_S = aux[AUX["r_S_ecef"].slice]
    sagnac = OMEGA_IE_RADPS / C_LIGHT_MPS * (r_S[0] * r_U[1] - r_S[1] * r_U[0])
    return ca.norm_2(r_S - r_U) + sagnac + x[X["c_dt"].offset]


OBSERVABLES = (
    R.Observable("PSEUDORANGE", "pseudorange", 0, h, "m", source="gnss", token="gps",
                 stream="pseudorange", table="satellite", constellation="gps", paper=True,
                 noise=R.Noise("gps.pseudorange_sigma_m", 3.0, 1e-3, 1e3, "1-sigma pseudorange noise"),
                 doc="GPS pseudorange, the paper's (atmosphere absorbed in R, GPS clock only)"),
)
