"""Strapdown mechanization in the local ENU frame of a fixed origin (CasADi SX).

Frame: ENU axes at the origin r0 (lat0, lon0, h0 in the parameters), fixed to the Earth,
so it rotates with the Earth at w_ie. Position p_enu, velocity v_enu = d p_enu/dt
(velocity w.r.t. the Earth), attitude q_nb (body -> this ENU frame). Equations:

    dv_enu/dt = C_b_n (f_b - b_a) + g_enu(p) - 2 w_ie^n x v_enu
    dC_b_n/dt = C_b_n [(w_b - b_g) x] - [w_ie^n x] C_b_n

Because the frame is fixed to the Earth there is no transport rate; the curvature of
the Earth enters only through gravity, evaluated at the current point: its magnitude
(Somigliana + height) and its direction (the ellipsoid normal there, expressed in the
origin's ENU axes). That direction change with horizontal position is what produces
the Schuler oscillation; the height dependence is what makes the unaided vertical
channel unstable. Valid within ~10 km of the origin (the ENU-plane formulation itself
is exact; the model ignores only the deflection of the vertical and tidal terms, and
numerics are checked in that region).

Integration over one IMU interval dt from increments u = [dtheta_b, dvel_b]:
- attitude: exact for constant rates, q+ = exp(-w_ie^n dt) (x) q (x) exp(dtheta_b - b_g dt),
  then normalized (formed from the half-interval rotations that also give q_mid);
- specific force: dvel_b - b_a dt rotated with the mid-interval attitude (this includes
  the first-order velocity-rotation correction 1/2 dtheta x dvel);
- gravity and Coriolis: trapezoid (Heun): evaluated at the start and at an Euler
  predicted end point, averaged; position by the trapezoid of the velocities.
"""
from __future__ import annotations

import casadi as ca

from leonav.models import constants as K
from leonav.models import dynamics, frames
from leonav.models.gravity import normal_gravity_sin
from leonav.models.state import AUX, P, U, X


def origin(p):
    """(lat0, lon0, h0, r0_ecef, C_n_e) of the ENU origin from the parameter vector."""
    lat0, lon0, h0 = p[P["lat0_rad"].offset], p[P["lon0_rad"].offset], p[P["h0_m"].offset]
    return lat0, lon0, h0, frames.ecef_from_geodetic(lat0, lon0, h0), frames.C_n_e(lat0, lon0)


def earth_rate_enu(p):
    """Earth rotation rate resolved in the origin's ENU axes (rad/s)."""
    lat0 = p[P["lat0_rad"].offset]
    return K.OMEGA_IE_RADPS * ca.vertcat(0, ca.cos(lat0), ca.sin(lat0))


def gravity_enu(p_enu, p):
    """Normal gravity vector (m/s^2) at position p_enu, in the origin's ENU axes.

    Magnitude from Somigliana at the point's own geodetic latitude and height; direction
    minus the ellipsoid normal at that point (so it tilts by ~distance/R away from the origin).
    """
    _, _, _, r0, C = origin(p)
    up_ecef, sin_lat, h = frames.ellipsoid_normal_from_ecef(r0 + C @ p_enu)
    return -normal_gravity_sin(sin_lat, h) * (C.T @ up_ecef)


def accel_enu(x, f_b, p):
    """Earth-relative acceleration d v_enu/dt (m/s^2) for specific force f_b (body, m/s^2)."""
    C_b_n = frames.rot_from_quat(x[X["q_nb"].slice])
    v = x[X["v_enu"].slice]
    w_ie = earth_rate_enu(p)
    return C_b_n @ (f_b - x[X["b_a"].slice]) + gravity_enu(x[X["p_enu"].slice], p) - 2 * ca.cross(w_ie, v)


def corrected_increments(x, u, dt):
    """Bias-corrected increments w = [dtheta_b - b_g dt, dvel_b - b_a dt] (rad, m/s).

    The biases enter the mechanization only through these, which the EKF uses to get the
    bias columns of F from the input Jacobian by the chain rule (models.ekf.nav_transition).
    """
    dtheta_b, dvel_b = u[U["dtheta_b"].slice], u[U["dvel_b"].slice]
    return ca.vertcat(dtheta_b - x[X["b_g"].slice] * dt, dvel_b - x[X["b_a"].slice] * dt)


def trapezoid_position(pos, vel, vel_next, dt):
    """Position after dt (s) by the trapezoid of the velocities: pos + (vel + vel_next) dt / 2.

    Linear, which models.ekf uses to factor F (see nav_predict).
    """
    return pos + (vel + vel_next) * dt / 2


def mech(x, u, dt, p):
    """Nominal state after one IMU interval `dt` (s) with increments u = [dtheta_b (rad), dvel_b (m/s)].

    Biases, clock, LO offset and inter-system biases follow their noise-free dynamics
    (constants, c_dt += c_ddt dt). See the module docstring for the integration scheme.
    """
    return mech_corrected(x, corrected_increments(x, u, dt), dt, p)


def mech_corrected(x, w, dt, p, gravity=None):
    """`mech` given the bias-corrected increments w = [phi (rad), dv (m/s)] (see corrected_increments).

    The biases and every other non-navigation block follow their own dynamics here
    (`models.dynamics.block_step`: a random walk's mean is constant). `gravity(pos_enu, p)` replaces
    `gravity_enu` (it is evaluated twice per step: at the start and at the predicted end).
    """
    gravity = gravity or gravity_enu
    pos, vel, q = x[X["p_enu"].slice], x[X["v_enu"].slice], x[X["q_nb"].slice]
    phi, dv_b = w[U["dtheta_b"].slice], w[U["dvel_b"].slice]  # w has the layout of u
    w_ie = earth_rate_enu(p)

    # half-interval rotations: q_mid = e_n (x) q (x) e_b, q_next = e_n (x) q_mid (x) e_b
    e_n, e_b = frames.quat_exp(-w_ie * dt / 2), frames.quat_exp(phi / 2)
    q_mid = frames.quat_mul(e_n, frames.quat_mul(q, e_b))
    q_next = frames.quat_mul(e_n, frames.quat_mul(q_mid, e_b))
    q_next = q_next * ca.sqrt(1 / ca.sumsqr(q_next))  # one division (see frames._bowring)
    dv_sf = frames.rot_from_quat(q_mid) @ dv_b

    def a_gc(pos_, vel_):  # gravity + Coriolis
        return gravity(pos_, p) - 2 * ca.cross(w_ie, vel_)

    a0 = a_gc(pos, vel)
    vel_pred = vel + dv_sf + a0 * dt
    pos_pred = trapezoid_position(pos, vel, vel_pred, dt)
    vel_next = vel + dv_sf + (a0 + a_gc(pos_pred, vel_pred)) * dt / 2
    pos_next = trapezoid_position(pos, vel, vel_next, dt)

    return ca.vertcat(pos_next, vel_next, q_next, *dynamics.block_step(x, dt, p))


def receiver_accel_ecef(x, aux, p):
    """Receiver Earth-relative acceleration in ECEF axes (m/s^2) from the state and aux f_b."""
    _, _, _, _, C = origin(p)
    return C @ accel_enu(x, aux[AUX["f_b"].slice], p)
