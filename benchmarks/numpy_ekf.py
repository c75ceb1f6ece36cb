"""Plain NumPy error-state EKF: the reference for `leonav bench` ONLY, not product code.

It runs the same filter as the generated C (same state, parameters, mechanization scheme,
process noise, Joseph update, chi-square gate), written the way a NumPy user would:
the equations in vectorized NumPy and the Jacobians F, G and H by forward finite
differences over a batch of perturbed states (one vectorized call per Jacobian). Only
the observables the benchmark uses are implemented (pseudorange, pos_e/n/u,
doppler_rate). Its estimates agree with the generated filter to the finite-difference
accuracy, which the benchmark prints as a cross-check.
"""
from __future__ import annotations

import math

import numpy as np

from leonav_runtime.gen import constants as K
from leonav_runtime.gen import state_layout as L

EPS = 1e-6  # finite-difference step on the error state and on the IMU increments

# x = [p_enu, v_enu | q_nb | b_a ... b_lo] and dx = [dp, dv | dtheta | db_a ... db_lo]: the
# outer groups are additive, the quaternion in between is retracted.
PV_X, PV_DX = slice(L.X_P_ENU, L.X_Q_NB), slice(L.DX_DP, L.DX_DTHETA)
REST_X, REST_DX = slice(L.X_B_A, L.NX), slice(L.DX_DB_A, L.NDX)
# mech() and boxplus() assemble x block by block in this order (docs/design.md)
_X_ORDER = ("P_ENU", "V_ENU", "Q_NB", "B_A", "B_G", "C_DT", "C_DDT", "DT_FIX", "B_LO")
assert [getattr(L, f"X_{n}") for n in _X_ORDER] == \
    list(np.cumsum([0] + [getattr(L, f"X_{n}_SIZE") for n in _X_ORDER[:-1]])), "numpy_ekf: x block order changed"
assert L.DX_DTHETA_SLICE.stop == L.DX_DB_A, "numpy_ekf: dx block order changed"


# ---- quaternions, batched over rows: q has shape (m, 4), [w x y z] --------------------

def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    aw, av, bw, bv = a[:, :1], a[:, 1:], b[:, :1], b[:, 1:]
    return np.hstack([aw * bw - np.sum(av * bv, axis=1, keepdims=True), aw * bv + bw * av + np.cross(av, bv)])


def quat_exp(phi: np.ndarray) -> np.ndarray:
    """Unit quaternion of rotation vectors phi (m, 3), rad."""
    a = np.linalg.norm(phi, axis=1, keepdims=True)
    small = a < 1e-8
    s = np.where(small, 0.5 - a * a / 48.0, np.sin(a / 2) / np.where(small, 1.0, a))
    return np.hstack([np.cos(a / 2), s * phi])


def rot(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (m, 3, 3) of unit quaternions q (m, 4)."""
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


# ---- Earth ------------------------------------------------------------------------------

def ecef_from_geodetic(lat: float, lon: float, h: float) -> np.ndarray:
    n = K.WGS84_A_M / math.sqrt(1 - K.WGS84_E2 * math.sin(lat) ** 2)
    return np.array([(n + h) * math.cos(lat) * math.cos(lon), (n + h) * math.cos(lat) * math.sin(lon),
                     (n * (1 - K.WGS84_E2) + h) * math.sin(lat)])


def enu_axes(lat: float, lon: float) -> np.ndarray:
    """C_n_e: columns are the East, North, Up unit vectors in ECEF."""
    sl, cl, so, co = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
    return np.array([[-so, -sl * co, cl * co], [co, -sl * so, cl * so], [0.0, cl, sl]])


def geodetic_from_ecef(r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lat, lon, h) of ECEF points r (m, 3), fixed-point iteration on the latitude."""
    x, y, z = r.T
    lon = np.arctan2(y, x)
    rho = np.hypot(x, y)
    lat = np.arctan2(z, rho * (1 - K.WGS84_E2))
    for _ in range(4):
        n = K.WGS84_A_M / np.sqrt(1 - K.WGS84_E2 * np.sin(lat) ** 2)
        h = rho / np.cos(lat) - n
        lat = np.arctan2(z, rho * (1 - K.WGS84_E2 * n / (n + h)))
    n = K.WGS84_A_M / np.sqrt(1 - K.WGS84_E2 * np.sin(lat) ** 2)
    return lat, lon, rho / np.cos(lat) - n


def normal_gravity(lat: np.ndarray, h: np.ndarray) -> np.ndarray:
    s2 = np.sin(lat) ** 2
    g0 = K.GAMMA_E_MPS2 * (1 + K.SOMIGLIANA_K * s2) / np.sqrt(1 - K.WGS84_E2 * s2)
    a = K.WGS84_A_M
    return g0 * (1 - 2 / a * (1 + K.WGS84_F + K.GRAVITY_M - 2 * K.WGS84_F * s2) * h + 3 * h * h / (a * a))


class NumpyEKF:
    """Error-state EKF in NumPy (benchmark reference). x (NX,), P (NDX, NDX), p (NP,)."""

    def __init__(self, x0, P0, p, gate_nis: float = K.CHI2_1DOF_999) -> None:
        self.x = np.array(x0, dtype=float)
        self.P = np.array(P0, dtype=float)
        self.p = np.array(p, dtype=float)
        self.gate = gate_nis
        lat0, lon0, h0 = self.p[L.P_LAT0_RAD], self.p[L.P_LON0_RAD], self.p[L.P_H0_M]
        self.r0 = ecef_from_geodetic(lat0, lon0, h0)
        self.C_n_e = enu_axes(lat0, lon0)
        self.w_ie = K.OMEGA_IE_RADPS * np.array([0.0, math.cos(lat0), math.sin(lat0)])
        self.n_applied = self.n_gated = self.n_failed = 0

    # -- model ------------------------------------------------------------------------
    def gravity(self, pos: np.ndarray) -> np.ndarray:
        r = self.r0 + pos @ self.C_n_e.T
        lat, lon, h = geodetic_from_ecef(r)
        up = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], -1)
        return -normal_gravity(lat, h)[:, None] * (up @ self.C_n_e)

    def mech(self, X: np.ndarray, U: np.ndarray, dt: float) -> np.ndarray:
        """Nominal states after dt for rows X (m, NX) with increments U (m, NU)."""
        pos, vel, q = X[:, L.X_P_ENU_SLICE], X[:, L.X_V_ENU_SLICE], X[:, L.X_Q_NB_SLICE]
        b_a, b_g = X[:, L.X_B_A_SLICE], X[:, L.X_B_G_SLICE]
        phi = U[:, L.U_DTHETA_B_SLICE] - b_g * dt
        e_full = quat_exp(np.tile(-self.w_ie * dt, (len(X), 1)))
        e_half = quat_exp(np.tile(-self.w_ie * dt / 2, (len(X), 1)))
        q_next = quat_mul(e_full, quat_mul(q, quat_exp(phi)))
        q_next /= np.linalg.norm(q_next, axis=1, keepdims=True)
        q_mid = quat_mul(e_half, quat_mul(q, quat_exp(phi / 2)))
        dv_sf = np.einsum("mij,mj->mi", rot(q_mid), U[:, L.U_DVEL_B_SLICE] - b_a * dt)

        def a_gc(pos_, vel_):
            return self.gravity(pos_) - 2 * np.cross(self.w_ie, vel_)

        a0 = a_gc(pos, vel)
        vel_pred = vel + dv_sf + a0 * dt
        pos_pred = pos + (vel + vel_pred) * dt / 2
        vel_next = vel + dv_sf + (a0 + a_gc(pos_pred, vel_pred)) * dt / 2
        pos_next = pos + (vel + vel_next) * dt / 2
        clock = np.column_stack([X[:, L.X_C_DT] + X[:, L.X_C_DDT] * dt, X[:, L.X_C_DDT:]])  # c_ddt and later: held
        return np.hstack([pos_next, vel_next, q_next, b_a, b_g, clock])

    @staticmethod
    def boxplus(x: np.ndarray, DX: np.ndarray) -> np.ndarray:
        q = quat_mul(np.tile(x[L.X_Q_NB_SLICE], (len(DX), 1)), quat_exp(DX[:, L.DX_DTHETA_SLICE]))
        return np.hstack([x[PV_X] + DX[:, PV_DX], q, x[REST_X] + DX[:, REST_DX]])

    @staticmethod
    def boxminus(X1: np.ndarray, x0: np.ndarray) -> np.ndarray:
        q0_inv = np.tile(x0[L.X_Q_NB_SLICE] * np.array([1.0, -1.0, -1.0, -1.0]), (len(X1), 1))
        dq = quat_mul(q0_inv, X1[:, L.X_Q_NB_SLICE])
        return np.hstack([X1[:, PV_X] - x0[PV_X], 2 * np.sign(dq[:, :1]) * dq[:, 1:], X1[:, REST_X] - x0[REST_X]])

    def h(self, kind: str, X: np.ndarray, aux: np.ndarray) -> np.ndarray:
        """Predicted measurement of `kind` for rows X (m, NX)."""
        if kind in ("pos_e", "pos_n", "pos_u"):
            i = "enu".index(kind[-1])      # a fix dt_fix late: the position dt_fix ago (no lever arm here)
            return X[:, L.X_P_ENU + i] - X[:, L.X_V_ENU + i] * X[:, L.X_DT_FIX]
        r_U = self.r0 + X[:, L.X_P_ENU_SLICE] @ self.C_n_e.T
        r_S = aux[L.AUX_R_S_ECEF_SLICE]
        if kind == "pseudorange":
            sagnac = K.OMEGA_IE_RADPS / K.C_LIGHT_MPS * (r_S[0] * r_U[:, 1] - r_S[1] * r_U[:, 0])
            return np.linalg.norm(r_S - r_U, axis=1) + sagnac + X[:, L.X_C_DT]
        if kind == "doppler_rate":
            v_U = X[:, L.X_V_ENU_SLICE] @ self.C_n_e.T
            f_b = aux[L.AUX_F_B_SLICE]
            a_enu = (np.einsum("mij,mj->mi", rot(X[:, L.X_Q_NB_SLICE]), f_b - X[:, L.X_B_A_SLICE])
                     + self.gravity(X[:, L.X_P_ENU_SLICE]) - 2 * np.cross(self.w_ie, X[:, L.X_V_ENU_SLICE]))
            a_U = a_enu @ self.C_n_e.T
            d = r_S - r_U
            rho = np.linalg.norm(d, axis=1)
            u = d / rho[:, None]
            v_rel = aux[L.AUX_V_S_ECEF_SLICE] - v_U
            rho_dot = np.sum(u * v_rel, axis=1)
            rho_ddot = (np.sum(u * (aux[L.AUX_A_S_ECEF_SLICE] - a_U), axis=1)
                        + (np.sum(v_rel * v_rel, axis=1) - rho_dot**2) / rho)
            return -(self.p[L.P_F_C_HZ] / K.C_LIGHT_MPS) * rho_ddot
        raise NotImplementedError(f"observable {kind!r} is not part of the NumPy benchmark reference")

    # -- filter -----------------------------------------------------------------------
    def predict(self, u: np.ndarray, dt: float) -> None:
        ndx, nu = L.NDX, L.NU
        X = np.vstack([self.x, self.boxplus(self.x, EPS * np.eye(ndx)), np.tile(self.x, (nu, 1))])
        U = np.tile(u, (1 + ndx + nu, 1))
        U[1 + ndx:] += EPS * np.eye(nu)
        out = self.mech(X, U, dt)
        x_next = out[0]
        F = (self.boxminus(out[1:1 + ndx], x_next) / EPS).T
        G = (self.boxminus(out[1 + ndx:], x_next) / EPS).T
        p = self.p
        Qd = G @ np.diag(np.r_[np.full(L.U_DTHETA_B_SIZE, p[L.P_ARW] ** 2 * dt),
                               np.full(L.U_DVEL_B_SIZE, p[L.P_VRW] ** 2 * dt)]) @ G.T
        ba, bg = np.r_[L.DX_DB_A_SLICE], np.r_[L.DX_DB_G_SLICE]
        Qd[ba, ba] += p[L.P_ACC_BIAS_RW] ** 2 * dt
        Qd[bg, bg] += p[L.P_GYRO_BIAS_RW] ** 2 * dt
        Qd[L.DX_DB_LO, L.DX_DB_LO] += p[L.P_Q_BLO] * dt
        c, d = L.DX_DC_DT, L.DX_DC_DDT
        Qd[c, c] += p[L.P_Q_CDT] * dt + p[L.P_Q_CDDT] * dt**3 / 3
        Qd[c, d] += p[L.P_Q_CDDT] * dt**2 / 2
        Qd[d, c] += p[L.P_Q_CDDT] * dt**2 / 2
        Qd[d, d] += p[L.P_Q_CDDT] * dt
        P = F @ self.P @ F.T + Qd
        self.x, self.P = x_next, (P + P.T) / 2

    def update(self, kind: str, z: float, R: float, aux: np.ndarray) -> int:
        """Scalar Joseph update; returns 0 applied, 1 gated, 2 failed."""
        X = np.vstack([self.x, self.boxplus(self.x, EPS * np.eye(L.NDX))])
        hs = self.h(kind, X, aux)
        H = (hs[1:] - hs[0]) / EPS
        y = z - hs[0]
        b = self.P @ H
        s = H @ b + R
        if not (s > 0 and np.isfinite(s)):
            self.n_failed += 1
            return 2
        if self.gate > 0 and y * y / s > self.gate:
            self.n_gated += 1
            return 1
        k = b / s
        P = self.P - np.outer(k, b) - np.outer(b, k) + s * np.outer(k, k)
        self.x = self.boxplus(self.x, (k * y)[None, :])[0]
        self.P = (P + P.T) / 2
        self.n_applied += 1
        return 0
