"""Generic error-state EKF pieces, built from a nominal model by differentiation (CasADi SX).

Nothing here knows the navigation equations: `predict` and `scalar_update` take the
nominal transition f(x, u), the retraction boxplus/boxminus and a measurement h(x), and
derive every Jacobian symbolically:
    F = d[f(x [+] dx, u) [-] f(x, u)]/d dx at dx = 0
    G = d[f(x, u + du) [-] f(x, u)]/d du at du = 0   (maps input noise to the error state)
    H = d[h(x [+] dx)]/d dx at dx = 0
The navigation instance (state layout, IMU noise, clock) is `nav_predict` / `nav_update`.
"""
from __future__ import annotations

from typing import Callable

import casadi as ca

from models import frames, kinematics
from models.clock import clock_qd
from models.state import DX, NDX, NU, P, U

Expr = ca.SX


def _at_zero(expr, sym):
    return ca.substitute(expr, sym, ca.DM.zeros(sym.shape))


def _sym(shape_like: int, name: str):
    return ca.SX.sym(name, shape_like)


def error_jacobian(f: Callable, x, boxplus: Callable, boxminus: Callable, ndx: int):
    """d[f(x [+] dx) [-] f(x)]/d dx at dx = 0 for a state-to-state map f."""
    dx = _sym(ndx, "dx")
    return _at_zero(ca.jacobian(boxminus(f(boxplus(x, dx)), f(x)), dx), dx)


def input_jacobian(f: Callable, u, boxminus: Callable):
    """d[f(u + du) [-] f(u)]/d du at du = 0 for a map from the input to the state."""
    du = _sym(u.shape[0], "du")
    return _at_zero(ca.jacobian(boxminus(f(u + du), f(u)), du), du)


def measurement_jacobian(h: Callable, x, boxplus: Callable, ndx: int):
    """d h(x [+] dx)/d dx at dx = 0 (row vector)."""
    dx = _sym(ndx, "dx")
    return _at_zero(ca.jacobian(h(boxplus(x, dx)), dx), dx)


def symmetrize(A):
    return (A + A.T) / 2


def covariance_predict(P_, F, Qd):
    """F P F^T + Qd (symmetrized). Works on SX and MX."""
    return symmetrize(ca.mtimes([F, P_, F.T]) + Qd)


def scalar_update(x, P_, z, R, h_pred, H, boxplus: Callable):
    """One scalar measurement update, Joseph form, from the prediction h_pred and its H (1 x n).

    Returns (x_post, P_post, y, S, nis) with y = z - h_pred, S = H P H^T + R,
    K = P H^T / S, P_post = (I - K H) P (I - K H)^T + K R K^T (Joseph), x_post = x [+] K y,
    nis = y^2 / S. The Joseph form is evaluated expanded, P - K b^T - b K^T + S K K^T with
    b = P H^T, which equals the product form for any gain and costs O(n^2), not O(n^3).
    The attitude covariance is not rotated by the reset (the reset Jacobian
    I - [K y]_theta x / 2 differs from I by the size of the attitude correction).
    Works on SX and MX (the generated functions use MX so the matrix products stay loops).
    """
    y = z - h_pred
    b = ca.mtimes(P_, H.T)
    S = ca.mtimes(H, b) + R
    K = b / S
    P_post = symmetrize(P_ - ca.mtimes(K, b.T) - ca.mtimes(b, K.T) + S * ca.mtimes(K, K.T))
    return boxplus(x, K * y), P_post, y, S, y * y / S


def information_add(J, H, R):
    """Fisher information after a scalar measurement: J + H^T H / R."""
    return J + ca.mtimes(H.T, H) / R


# --- navigation instance ---------------------------------------------------------------

def nav_process_noise(x, u, dt, p):
    """Discrete process noise Qd (NDX x NDX) of the navigation error state over dt.

    IMU white noise enters through the increments: Cov(dtheta_b) = arw^2 dt I,
    Cov(dvel_b) = vrw^2 dt I, mapped by G = d(mech [-] mech)/du (obtained by
    differentiation), so Qd_imu = G diag(...) G^T (first order, noise injected at
    the increment). Bias random walks: acc_bias_rw^2 dt, gyro_bias_rw^2 dt on their
    blocks (first order). Clock: exact two-state discretization; LO offset: q_blo dt.
    """
    G = input_jacobian(lambda uu: kinematics.mech(x, uu, dt, p), u, frames.boxminus)
    def par(name):
        return p[P[name].offset]
    var_u = ca.vertcat(
        ca.repmat(par("arw") ** 2 * dt, U["dtheta_b"].size, 1),
        ca.repmat(par("vrw") ** 2 * dt, U["dvel_b"].size, 1),
    )
    Qd = G @ ca.diag(var_u) @ G.T
    diag_extra = ca.SX.zeros(NDX)
    diag_extra[DX["db_a"].slice] = par("acc_bias_rw") ** 2 * dt
    diag_extra[DX["db_g"].slice] = par("gyro_bias_rw") ** 2 * dt
    diag_extra[DX["db_lo"].offset] = par("q_blo") * dt
    Qd = Qd + ca.diag(diag_extra)
    q11, q12, q22 = clock_qd(par("q_cdt"), par("q_cddt"), dt)
    i, j = DX["dc_dt"].offset, DX["dc_ddt"].offset
    Qd[i, i] += q11
    Qd[i, j] += q12
    Qd[j, i] += q12
    Qd[j, j] += q22
    return symmetrize(Qd)


def nav_transition(x, u, dt, p):
    """(x_next, F, Qd) of the navigation model over one IMU interval (SX)."""
    x_next = kinematics.mech(x, u, dt, p)
    F = error_jacobian(lambda xx: kinematics.mech(xx, u, dt, p), x, frames.boxplus, frames.boxminus, NDX)
    return x_next, F, nav_process_noise(x, u, dt, p)


def nav_predict(x, P_, u, dt, p):
    """(x_next, P_next, F, Qd) of the navigation filter over one IMU interval (SX)."""
    x_next, F, Qd = nav_transition(x, u, dt, p)
    return x_next, covariance_predict(P_, F, Qd), F, Qd


def nav_h(h: Callable, x, aux, p):
    """(prediction, H) of a navigation observable h(x, aux, p) (SX)."""
    hx = lambda xx: h(xx, aux, p)  # noqa: E731
    return hx(x), measurement_jacobian(hx, x, frames.boxplus, NDX)


def nav_update(h: Callable, x, P_, z, R, aux, p):
    """Scalar update of the navigation filter with measurement model h(x, aux, p) (SX)."""
    h_pred, H = nav_h(h, x, aux, p)
    return scalar_update(x, P_, z, R, h_pred, H, frames.boxplus)


assert NU == 6
