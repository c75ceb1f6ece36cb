"""Receiver ECEF state from the navigation state, and line-of-sight range kinematics."""
from __future__ import annotations

import casadi as ca

from leonav.models import kinematics
from leonav.models.constants import C_LIGHT_MPS
from leonav.models.state import X

LIGHT_TIME_ITERATIONS = 2  # fixed-point steps of tau = |r_S(t - tau) - r_U| / c; the second changes r_tx by < 1 um


def receiver_ecef(x, p):
    """(r_U, v_U) receiver position (m) and Earth-relative velocity (m/s), ECEF axes."""
    _, _, _, r0, C = kinematics.origin(p)
    return r0 + C @ x[X["p_enu"].slice], C @ x[X["v_enu"].slice]


def range_rate_accel(r_S, v_S, a_S, r_U, v_U, a_U):
    """(rho, rho_dot, rho_ddot) of the range |r_S - r_U| (m, m/s, m/s^2), all inputs ECEF.

    rho_ddot = u.(a_S - a_U) + (|v_rel|^2 - (u.v_rel)^2)/rho, u = (r_S - r_U)/rho (paper eq. 3,
    with the receiver acceleration kept).
    """
    r = r_S - r_U
    rho = ca.norm_2(r)
    u = r / rho
    v_rel = v_S - v_U
    rho_dot = ca.dot(u, v_rel)
    rho_ddot = ca.dot(u, a_S - a_U) + (ca.dot(v_rel, v_rel) - rho_dot**2) / rho
    return rho, rho_dot, rho_ddot


def transmit_state(r_S, v_S, a_S, r_U):
    """Satellite state at the transmit time of a signal received at r_U (all ECEF, m, m/s, m/s^2).

    The satellite moves along its ECEF Taylor expansion over the light time tau (~70 ms for
    GPS, error far below a millimetre): r_tx = r_S - v_S tau + a_S tau^2 / 2, with tau the
    fixed point of tau = |r_tx - r_U| / c started at |r_S - r_U| / c. Returns (r_tx, v_tx,
    tau) with r_tx in the ECEF frame of the transmit epoch (the pseudorange model adds the
    Sagnac term for the Earth's rotation during the flight).
    """
    tau = ca.norm_2(r_S - r_U) / C_LIGHT_MPS
    r_tx = r_S
    for _ in range(LIGHT_TIME_ITERATIONS):
        r_tx = r_S - v_S * tau + 0.5 * a_S * tau**2
        tau = ca.norm_2(r_tx - r_U) / C_LIGHT_MPS
    return r_tx, v_S - a_S * tau, tau
