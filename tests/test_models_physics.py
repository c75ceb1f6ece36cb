"""Physics of the compiled mechanization, run in long loops through casadi fold/mapaccum.

Site: Rochester, NY (43.0848638 N, -77.6786127 E, 170 m). "Perfect IMU" increments are
those of a body at rest on the rotating Earth: dtheta_b = C_n_b w_ie dt and
dvel_b = -C_n_b g(p) dt.
"""
from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from leonav.codegen.compiled import external
from leonav_runtime.gen import state_layout as L
from leonav_runtime.core.params import build_params

P_VEC = np.array(build_params(math.radians(43.0848638), math.radians(-77.6786127), 170.0))


@pytest.fixture(scope="module")
def gen():
    names = ("leonav_mech", "leonav_gravity_enu", "leonav_earth_rate_enu", "leonav_q_from_euler", "leonav_boxminus")
    return {n.removeprefix("leonav_"): external(n) for n in names}


def _vec(dm) -> np.ndarray:
    return np.array(dm).ravel()


def _rest_imu(gen, p_enu, q, dt):
    """Increments of a perfect IMU at rest at p_enu with attitude q (body -> ENU)."""
    w = q[0]
    v = q[1:]
    C_b_n = (w * w - v @ v) * np.eye(3) + 2 * np.outer(v, v) + 2 * w * np.array(
        [[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    g = _vec(gen["gravity_enu"](p_enu, P_VEC))
    w_ie = _vec(gen["earth_rate_enu"](P_VEC))
    u = np.zeros(L.NU)
    u[L.U_DTHETA_B_SLICE], u[L.U_DVEL_B_SLICE] = C_b_n.T @ w_ie * dt, -C_b_n.T @ g * dt
    return u


def _state(p_enu, q):
    x = np.zeros(L.NX)
    x[L.X_P_ENU_SLICE], x[L.X_Q_NB_SLICE] = p_enu, q
    return x


E, N, U = range(3)  # ENU axes within a position or velocity block


def test_gravity_and_earth_rate_values(gen):
    """Somigliana at the site (independent closed form) and Earth rate components."""
    lat = math.radians(43.0848638)
    s2 = math.sin(lat) ** 2
    g_ell = 9.7803253359 * (1 + 0.00193185265241 * s2) / math.sqrt(1 - 0.00669437999013 * s2)
    g = _vec(gen["gravity_enu"](np.zeros(3), P_VEC))
    assert g[U] == pytest.approx(-(g_ell - 3.0877e-6 * 170 * (1 - 0.0014 * s2)), abs=2e-6)
    assert abs(g[E]) < 1e-12 and abs(g[N]) < 1e-12
    # free-air gradient ~ -3.086e-6 s^-2 and tilt of the vertical ~ distance / R
    g_up = _vec(gen["gravity_enu"](np.array([0, 0, 1000.0]), P_VEC))
    assert (g_up[U] - g[U]) / 1000 == pytest.approx(3.086e-6, rel=0.01)
    g_east = _vec(gen["gravity_enu"](np.array([5000.0, 0, 0]), P_VEC))
    assert g_east[E] / g_east[U] == pytest.approx(5000.0 / 6.388e6, rel=0.01)
    w = _vec(gen["earth_rate_enu"](P_VEC))
    assert np.linalg.norm(w) == pytest.approx(7.292115e-5) and w[E] == 0 and w[U] / w[N] == pytest.approx(math.tan(lat))


def test_stationary_perfect_imu_stays_put_600s(gen):
    """At rest, tilted, 3 km from the origin: 600 s at 100 Hz, drift < 1 mm and < 1e-9 rad."""
    dt, n = 0.01, 60_000
    p0 = np.array([3000.0, -2000.0, 40.0])
    q0 = _vec(gen["q_from_euler"](np.radians([3.0, -5.0, 30.0])))
    u = _rest_imu(gen, p0, q0, dt)
    x0 = _state(p0, q0)
    x_end = _vec(gen["mech"].fold(n)(x0, u, dt, P_VEC))
    assert np.linalg.norm(x_end[L.X_P_ENU_SLICE] - p0) < 1e-3
    assert np.linalg.norm(x_end[L.X_V_ENU_SLICE]) < 1e-5
    assert np.linalg.norm(_vec(gen["boxminus"](x_end, x0))[L.DX_DTHETA_SLICE]) < 1e-9


def test_quaternion_stays_unit_over_1e6_steps(gen):
    """10^6 steps of a spinning body: |q| = 1 to 1e-12, attitude equals the closed form."""
    dt, n = 0.01, 1_000_000
    w_b = np.array([0.3, -0.2, 0.5])  # rad/s, constant body rate
    x0 = _state(np.zeros(3), np.array([1.0, 0, 0, 0]))
    u = np.zeros(L.NU)
    u[L.U_DTHETA_B_SLICE] = w_b * dt
    # The attitude update depends only on q, b_g, u, dt and the site: the translational
    # states (here in free fall) do not feed back into it. Two nested folds (1000 x 1000)
    # keep the loop in compiled code at linear cost.
    x_sym = ca.MX.sym("x", L.NX)
    chunk = ca.Function("chunk", [x_sym], [gen["mech"].fold(1000)(x_sym, u, dt, P_VEC)])
    x_end = _vec(chunk.fold(n // 1000)(x0))
    q = x_end[L.X_Q_NB_SLICE]
    assert abs(np.linalg.norm(q) - 1) < 1e-12
    # closed form: q(T) = exp(-w_ie T) (x) q0 (x) exp(w_b T)
    T = n * dt
    w_ie = _vec(gen["earth_rate_enu"](P_VEC))

    def qexp(phi):
        a = np.linalg.norm(phi)
        return np.r_[math.cos(a / 2), math.sin(a / 2) * phi / a]

    def qmul(p, r):
        return np.r_[p[0] * r[0] - p[1:] @ r[1:], p[0] * r[1:] + r[0] * p[1:] + np.cross(p[1:], r[1:])]

    q_ref = qmul(qexp(-w_ie * T), qmul(x0[L.X_Q_NB_SLICE], qexp(w_b * T)))
    ref = x_end.copy()
    ref[L.X_Q_NB_SLICE] = q_ref
    assert np.linalg.norm(_vec(gen["boxminus"](x_end, ref))[L.DX_DTHETA_SLICE]) < 1e-7


def _zero_crossings(t, s):
    idx = np.nonzero(np.sign(s[:-1]) * np.sign(s[1:]) < 0)[0]
    return t[idx] - s[idx] * (t[idx + 1] - t[idx]) / (s[idx + 1] - s[idx])


def test_tilt_error_gives_schuler_oscillation(gen):
    """0.1 mrad initial roll error at rest, vertical channel clamped: period ~ 84.4 min.

    0.1 mrad (not 1 mrad) keeps the Schuler excursion (~2 R tilt = 1.3 km) inside the
    model's ~10 km validity region.
    """
    dt, n = 0.5, 4 * 3600 * 2  # 4 h at 2 Hz
    q_true = np.array([1.0, 0, 0, 0])
    u = _rest_imu(gen, np.zeros(3), q_true, dt)
    q0 = _vec(gen["q_from_euler"](np.array([1e-4, 0, 0])))
    x_sym = ca.MX.sym("x", L.NX)
    x_next = gen["mech"](x_sym, u, dt, P_VEC)
    clamp = ca.DM.ones(L.NX)
    clamp[L.X_P_ENU + U], clamp[L.X_V_ENU + U] = 0, 0
    step = ca.Function("clamped", [x_sym], [x_next * clamp])
    traj = np.array(step.mapaccum(n)(_state(np.zeros(3), q0)))
    t = dt * np.arange(1, n + 1)
    v_n = traj[L.X_V_ENU + N]  # roll error -> north-south specific force error
    assert np.abs(traj[L.X_P_ENU + N]).max() > 100, "expected a Schuler excursion of order 2 * R * 1e-4"
    crossings = _zero_crossings(t, v_n)
    assert len(crossings) >= 5
    period = 2 * np.mean(np.diff(crossings))
    expected = 2 * math.pi * math.sqrt(6.371e6 / 9.804)  # 84.4 min
    assert period == pytest.approx(expected, rel=0.01), f"period {period / 60:.2f} min"
    # bounded: the error oscillates instead of growing quadratically
    assert np.abs(traj[L.X_P_ENU + N]).max() < 3 * 6.371e6 * 1e-4


def test_unaided_vertical_channel_diverges(gen):
    """1 m initial height error at rest: h grows like cosh(t/tau), tau = 1/sqrt(2g/R) ~ 570 s."""
    dt, n = 0.5, 6000  # 3000 s
    u = _rest_imu(gen, np.zeros(3), np.array([1.0, 0, 0, 0]), dt)
    traj = np.array(gen["mech"].mapaccum(n)(_state(np.array([0, 0, 1.0]), np.array([1.0, 0, 0, 0])),
                                          np.tile(u[:, None], n), dt, P_VEC))
    t = dt * np.arange(1, n + 1)
    h = traj[L.X_P_ENU + U]
    assert h[-1] > 50, "vertical error should have grown by well over an order of magnitude"
    late = t > 1500
    slope = np.polyfit(t[late], np.log(h[late]), 1)[0]  # cosh ~ exp(t/tau)/2 for t >> tau
    tau = 1 / math.sqrt(3.086e-6)  # from the normal-gravity free-air gradient
    assert 1 / slope == pytest.approx(tau, rel=0.03), f"tau {1 / slope:.0f} s"
    np.testing.assert_allclose(h, np.cosh(t / tau), rtol=0.05)
