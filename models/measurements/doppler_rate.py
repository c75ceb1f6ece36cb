"""Starlink beacon Doppler-rate (Hz/s), paper eqs. 3-4: alpha = -(f_c/c) rho_ddot.

rho_ddot = u.(a_S - a_U) + (|v_rel|^2 - (u.v_rel)^2)/rho, all ECEF (Earth-relative
velocities and accelerations). The receiver acceleration a_U comes from the state and
the latest specific force in aux (f_b, body):
a_U = C_n_e (C_b_n (f_b - b_a) + g(p) - 2 w_ie x v_enu), the same equation the
mechanization integrates. The LO offset is modelled constant, so it has no rate term.
"""
from __future__ import annotations

from leonav.models import kinematics
from leonav.models import registry as R
from leonav.models.constants import C_LIGHT_MPS
from leonav.models.measurements.geometry import range_rate_accel, receiver_ecef
from leonav.models.state import AUX, P


def h(x, aux, p):
    """Predicted Doppler rate (Hz/s) at carrier f_c_hz (parameter)."""
    r_U, v_U = receiver_ecef(x, p)
    a_U = kinematics.receiver_accel_ecef(x, aux, p)
    _, _, rho_ddot = range_rate_accel(
        aux[AUX["r_S_ecef"].slice], aux[AUX["v_S_ecef"].slice], aux[AUX["a_S_ecef"].slice], r_U, v_U, a_U
    )
    return -(p[P["f_c_hz"].offset] / C_LIGHT_MPS) * rho_ddot


OBSERVABLES = (
    R.Observable("DOPPLER_RATE", "doppler_rate", 7, h, "Hz/s", source="leo", token="alpha", stream="doppler_rate",
                 table="satellite", constellation="starlink", paper=True, input_noise=True,
                 # the paper's five matched beacons: median |d alpha| 0.8 Hz/s -> sigma = 0.8/0.6745 = 1.19
                 noise=R.Noise("starlink.doppler_rate_sigma_hz_s", 1.2, 1e-4, 1e3, "beacon Doppler-rate noise"),
                 doc="Starlink beacon Doppler-rate, paper eqs. 3-4 (receiver acceleration included)"),
)
