"""Rotations, quaternions, WGS84 geodesy and the error-state retraction (CasADi SX).

Conventions (docs/design.md): quaternions are [w, x, y, z] Hamilton products;
`q_nb` rotates body (forward-left-up) vectors into ENU, `v_n = C_b_n v_b`;
`C_b_n = Rz(yaw) Ry(pitch) Rx(roll)`, yaw counted from East towards North.
The attitude error is a body-frame (right) perturbation: `q_true = q_nom (x) exp(dtheta/2)`.
Every function here works on casadi SX/MX expressions (and on numbers through them).
"""
from __future__ import annotations

import casadi as ca

from leonav.models import constants as K
from leonav.models.state import DX, X

# Below this squared angle (rad^2) the quaternion exp/log use their Taylor series
# (4th order in the angle: truncation < 1e-17 there), which keeps the expressions and
# their derivatives finite at zero rotation, where Jacobians are taken.
_SMALL_ANGLE2 = 1e-4


def quat_mul(p, q):
    """Hamilton product p (x) q of [w x y z] quaternions."""
    pw, pv = p[0], p[1:4]
    qw, qv = q[0], q[1:4]
    w = pw * qw - ca.dot(pv, qv)
    v = pw * qv + qw * pv + ca.cross(pv, qv)
    return ca.vertcat(w, v)


def quat_conj(q):
    """Conjugate (inverse of a unit quaternion)."""
    return ca.vertcat(q[0], -q[1:4])


def quat_exp(phi):
    """Unit quaternion of the rotation vector `phi` (rad): [cos(|phi|/2), sin(|phi|/2) phi/|phi|]."""
    a2 = ca.dot(phi, phi)
    a = ca.sqrt(ca.fmax(a2, _SMALL_ANGLE2))  # never 0: the unused branch stays finite
    w_exact, s_exact = ca.cos(a / 2), ca.sin(a / 2) / a
    w_series = 1 - a2 / 8 + a2**2 * (1 / 384)  # products with constants: no divisions in C
    s_series = 0.5 - a2 * (1 / 48) + a2**2 * (1 / 3840)
    small = a2 < _SMALL_ANGLE2
    return ca.vertcat(ca.if_else(small, w_series, w_exact), ca.if_else(small, s_series, s_exact) * phi)


def quat_log(q):
    """Rotation vector (rad) of a unit quaternion, in (-pi, pi]; q and -q give the same result."""
    sign = ca.if_else(q[0] < 0, -1, 1)
    w, v = sign * q[0], sign * q[1:4]
    s2 = ca.dot(v, v)
    s = ca.sqrt(ca.fmax(s2, _SMALL_ANGLE2))
    # angle = 2 atan2(s, w); factor = angle / s, series in s^2 for small s (w ~ 1)
    factor_exact = 2 * ca.atan2(s, w) / s
    r2 = s2 / (w * w)
    factor_series = (2 / w) * (1 - r2 / 3 + r2**2 / 5 - r2**3 / 7)
    factor = ca.if_else(s2 < _SMALL_ANGLE2, factor_series, factor_exact)
    return factor * v


def rot_from_quat(q):
    """Rotation matrix of a unit quaternion: for q_nb this is C_b_n (v_n = C_b_n v_b)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    return ca.vertcat(
        ca.horzcat(1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
        ca.horzcat(2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
        ca.horzcat(2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)),
    )


def quat_from_euler(rpy):
    """q_nb from [roll, pitch, yaw] (rad), C_b_n = Rz(yaw) Ry(pitch) Rx(roll)."""
    half = rpy / 2
    qx = ca.vertcat(ca.cos(half[0]), ca.sin(half[0]), 0, 0)
    qy = ca.vertcat(ca.cos(half[1]), 0, ca.sin(half[1]), 0)
    qz = ca.vertcat(ca.cos(half[2]), 0, 0, ca.sin(half[2]))
    return quat_mul(qz, quat_mul(qy, qx))


def euler_from_quat(q):
    """[roll, pitch, yaw] (rad) of q_nb, inverse of `quat_from_euler` (pitch in [-pi/2, pi/2])."""
    C = rot_from_quat(q)
    roll = ca.atan2(C[2, 1], C[2, 2])
    pitch = ca.asin(ca.fmin(ca.fmax(-C[2, 0], -1), 1))
    yaw = ca.atan2(C[1, 0], C[0, 0])
    return ca.vertcat(roll, pitch, yaw)


def ecef_from_geodetic(lat, lon, h):
    """WGS84 geodetic (rad, rad, m) -> ECEF position (m)."""
    n = K.WGS84_A_M / ca.sqrt(1 - K.WGS84_E2 * ca.sin(lat) ** 2)
    return ca.vertcat(
        (n + h) * ca.cos(lat) * ca.cos(lon),
        (n + h) * ca.cos(lat) * ca.sin(lon),
        (n * (1 - K.WGS84_E2) + h) * ca.sin(lat),
    )


def _bowring(r_ecef):
    """Bowring's one-step closed form without trigonometric calls.

    Returns (num, den, rho, den_over_rho, 1 / hyp) with geodetic latitude lat = atan2(num, den),
    sin(lat) = num / hyp, cos(lat) = den / hyp, rho = sqrt(x^2 + y^2) and den / rho kept
    separately so that cos(lat) cos(lon) = x (den / rho) / hyp stays finite at rho = 0.
    The parametric latitude theta = atan2(z a, rho b) enters only through its sine and
    cosine, z a / D and rho b / D with D = hypot(z a, rho b).
    """
    x, y, z = r_ecef[0], r_ecef[1], r_ecef[2]
    a, b = K.WGS84_A_M, K.WGS84_B_M
    rho2 = x * x + y * y
    D2 = (z * a) ** 2 + rho2 * b * b
    # reciprocals as sqrt(1 / x): one division each, and cheaper derivatives (casadi would
    # fold a product with 1 / x back into a division)
    inv_D2 = 1 / D2
    inv_D3 = inv_D2 * ca.sqrt(inv_D2)
    num = z + K.WGS84_EP2 * b * (z * a) ** 3 * inv_D3
    den_over_rho = 1 - K.WGS84_E2 * a * b**3 * rho2 * inv_D3
    rho = ca.sqrt(rho2)
    den = rho * den_over_rho
    return num, den, rho, den_over_rho, ca.sqrt(1 / (num * num + den * den))


def _height(r_ecef, sin_lat, cos_lat, rho):
    return rho * cos_lat + r_ecef[2] * sin_lat - K.WGS84_A_M * ca.sqrt(1 - K.WGS84_E2 * sin_lat * sin_lat)


def geodetic_from_ecef(r_ecef):
    """ECEF (m) -> WGS84 (lat rad, lon rad, h m) with Bowring's one-step closed form.

    Error well below 1 mm in height and 1e-10 rad in latitude for points within a few
    km of the Earth's surface, which covers the ENU frame's validity region. Closed form
    (no iteration), so it is differentiable and cheap inside the mechanization.
    """
    num, den, rho, _, inv_hyp = _bowring(r_ecef)
    h = _height(r_ecef, num * inv_hyp, den * inv_hyp, rho)
    return ca.atan2(num, den), ca.atan2(r_ecef[1], r_ecef[0]), h


def ellipsoid_normal_from_ecef(r_ecef):
    """(up_ecef, sin_lat, h): unit ellipsoid normal (ECEF), sin(geodetic latitude) and height (m).

    The same Bowring solution as `geodetic_from_ecef`, but only square roots and divisions
    (up = [cos lat cos lon, cos lat sin lon, sin lat] from the ratios), which makes it and
    its derivatives much cheaper in the mechanization, where gravity is evaluated.
    """
    num, den, rho, den_over_rho, inv_hyp = _bowring(r_ecef)
    sin_lat = num * inv_hyp
    cos_over_rho = den_over_rho * inv_hyp
    up = ca.vertcat(r_ecef[0] * cos_over_rho, r_ecef[1] * cos_over_rho, sin_lat)
    return up, sin_lat, _height(r_ecef, sin_lat, den * inv_hyp, rho)


def C_n_e(lat, lon):
    """Rotation ENU -> ECEF at (lat, lon): columns are the East, North, Up unit vectors in ECEF.

    `r_ecef = r0 + C_n_e p_enu`; its transpose maps ECEF vectors into ENU.
    """
    sl, cl, so, co = ca.sin(lat), ca.cos(lat), ca.sin(lon), ca.cos(lon)
    return ca.vertcat(
        ca.horzcat(-so, -sl * co, cl * co),
        ca.horzcat(co, -sl * so, cl * so),
        ca.horzcat(0, cl, sl),
    )


def boxplus(x, dx):
    """x [+] dx: vector blocks add, attitude q (x) exp(dtheta/2) (body-frame perturbation)."""
    q = x[X["q_nb"].slice]
    q_new = quat_mul(q, quat_exp(dx[DX["dtheta"].slice]))
    q_blk, th_blk = X["q_nb"].slice, DX["dtheta"].slice
    before = dx[0 : th_blk.start]
    after = dx[th_blk.stop :]
    return ca.vertcat(x[0 : q_blk.start] + before, q_new, x[q_blk.stop :] + after)


def boxminus(x1, x0):
    """x1 [-] x0: the dx with x0 [+] dx = x1 (attitude: 2 log(q0^-1 (x) q1), body frame)."""
    q0, q1 = x0[X["q_nb"].slice], x1[X["q_nb"].slice]
    dtheta = quat_log(quat_mul(quat_conj(q0), q1))
    i, j = X["q_nb"].slice.start, X["q_nb"].slice.stop
    return ca.vertcat(x1[0:i] - x0[0:i], dtheta, x1[j:] - x0[j:])


def level_from_specific_force(f_b):
    """Roll and pitch (rad) of a body at rest from its mean specific force f_b (m/s^2, body FLU).

    At rest the accelerometer measures -g, i.e. +|g| along the ENU up axis, so with
    C_b_n = Rz(yaw) Ry(pitch) Rx(roll): roll = atan2(f_y, f_z), pitch = atan2(-f_x,
    sqrt(f_y^2 + f_z^2)). Yaw is not observable from the accelerometer.
    """
    return ca.vertcat(ca.atan2(f_b[1], f_b[2]), ca.atan2(-f_b[0], ca.sqrt(f_b[1] ** 2 + f_b[2] ** 2)))
