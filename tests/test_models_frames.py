"""Frames, quaternions, geodesy, retraction, noise profiles: checks against independent references."""
from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from leonav.models import frames
from leonav.models.clock import TCXO
from leonav.models.imu import TACTICAL, WT901
from leonav_runtime.gen import state_layout as L
from leonav_runtime.core.params import build_params
from tests import symbolic

FNS = symbolic.FNS  # built on first use, once per process


def _num(expr_fn, *args):
    syms = [ca.SX.sym(f"a{i}", np.size(a)) for i, a in enumerate(args)]
    out = expr_fn(*syms)
    outs = out if isinstance(out, tuple) else (out,)
    res = ca.Function("f", syms, list(outs))(*args)
    res = res if isinstance(res, tuple) else (res,)
    vals = [np.array(r).squeeze() for r in res]
    return vals if len(vals) > 1 else vals[0]


def _rx(a):
    return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])


def _ry(a):
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


def _rz(a):
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])


def test_euler_convention_and_round_trip():
    rpy = np.array([0.3, -0.4, 2.5])
    q = _num(frames.quat_from_euler, rpy)
    C = _num(lambda qq: frames.rot_from_quat(qq), q)
    np.testing.assert_allclose(C, _rz(rpy[2]) @ _ry(rpy[1]) @ _rx(rpy[0]), atol=1e-15)
    np.testing.assert_allclose(_num(frames.euler_from_quat, q), rpy, atol=1e-14)
    # yaw = +90 deg faces North: body forward maps to ENU north
    C_north = _num(lambda qq: frames.rot_from_quat(qq), _num(frames.quat_from_euler, np.array([0, 0, math.pi / 2])))
    np.testing.assert_allclose(C_north @ [1, 0, 0], [0, 1, 0], atol=1e-15)


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-3, 0.00999, 0.01001, 0.5, 3.0])
def test_exp_log_round_trip_across_the_series_switch(angle):
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    phi = angle * axis
    q = _num(frames.quat_exp, phi)
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)
    assert q[0] == pytest.approx(math.cos(angle / 2), abs=2.3e-16)
    np.testing.assert_allclose(q[1:], math.sin(angle / 2) * axis, atol=1e-17)
    np.testing.assert_allclose(_num(frames.quat_log, q), phi, atol=1e-15)
    np.testing.assert_allclose(_num(frames.quat_log, -q), phi, atol=1e-15)  # q and -q are one rotation


def test_boxplus_boxminus_are_inverse_and_body_frame():
    rng = np.random.default_rng(1)
    x = rng.normal(size=L.NX)
    x[L.X_Q_NB_SLICE] /= np.linalg.norm(x[L.X_Q_NB_SLICE])
    dx = rng.normal(size=L.NDX) * 0.1
    x1 = np.array(FNS["leonav_boxplus"](x, dx)).ravel()
    np.testing.assert_allclose(np.array(FNS["leonav_boxminus"](x1, x)).ravel(), dx, atol=1e-14)
    # attitude perturbation is on the right: C(x1) = C(x) Exp(dtheta)
    C0 = _num(lambda q: frames.rot_from_quat(q), x[L.X_Q_NB_SLICE])
    C1 = _num(lambda q: frames.rot_from_quat(q), x1[L.X_Q_NB_SLICE])
    dth = dx[L.DX_DTHETA_SLICE]
    a = np.linalg.norm(dth)
    K = np.array([[0, -dth[2], dth[1]], [dth[2], 0, -dth[0]], [-dth[1], dth[0], 0]]) / a
    Exp = np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K
    np.testing.assert_allclose(C1, C0 @ Exp, atol=1e-14)


def test_geodesy_against_skyfield_and_round_trip():
    wgs84 = pytest.importorskip("skyfield.api").wgs84
    for lat, lon, h in ((43.0848638, -77.6786127, 170.0), (-33.9, 151.2, 2500.0), (89.9, 10.0, -30.0)):
        r = _num(lambda a, b, c: frames.ecef_from_geodetic(a[0], b[0], c[0]),
                 np.array([math.radians(lat)]), np.array([math.radians(lon)]), np.array([h]))
        ref = wgs84.latlon(lat, lon, h).itrs_xyz.m
        np.testing.assert_allclose(r, ref, atol=1e-6)
        lat2, lon2, h2 = _num(frames.geodetic_from_ecef, r)
        assert lat2 == pytest.approx(math.radians(lat), abs=1e-11)
        assert lon2 == pytest.approx(math.radians(lon), abs=1e-12)
        assert h2 == pytest.approx(h, abs=1e-4)
    C = _num(lambda a, b: frames.C_n_e(a[0], b[0]), np.array([0.0]), np.array([0.0]))
    np.testing.assert_allclose(C, [[0, 0, 1], [1, 0, 0], [0, 1, 0]], atol=1e-16)  # E=y, N=z, U=x at (0, 0)


def test_noise_profiles_and_discrete_noise():
    # tactical: 0.1 deg/sqrt(h) = 2.909e-5 rad/sqrt(s); 0.03 m/s/sqrt(h) = 5e-4 m/s/sqrt(s)
    assert TACTICAL.arw == pytest.approx(2.9089e-5, rel=1e-4)
    assert TACTICAL.vrw == pytest.approx(5e-4)
    assert TACTICAL.gyro_bias_sigma == pytest.approx(4.8481e-6, rel=1e-4)
    assert WT901.acc_bias_sigma == pytest.approx(0.005 * 9.80665)
    assert WT901.gyro_bias_sigma == pytest.approx(math.radians(0.05))
    p = np.array(build_params(0.75, -1.35, 170.0, imu=TACTICAL, clock=TCXO, q_blo=0.04))
    x = np.zeros(L.NX)
    x[L.X_Q_NB_SLICE] = np.array(FNS["leonav_q_from_euler"](np.array([0.1, 0.2, 1.0]))).ravel()
    dt = 0.5
    u = np.zeros(L.NU)
    u[L.U_DVEL_B + 2] = 9.8 * dt  # level, specific force up
    Qd = np.array(FNS["leonav_predict"](x, np.eye(L.NDX), u, dt, p)[3])
    q_diag = np.diag(Qd)
    np.testing.assert_allclose(np.linalg.eigvalsh(Qd).min() >= -1e-20, True)
    # velocity: VRW (rotation-invariant) plus the ARW seen through the mid-interval attitude,
    # at most |dvel|^2 arw^2 dt / 4 per axis
    coupling = (9.8 * dt) ** 2 * TACTICAL.arw**2 * dt / 4
    assert np.all(q_diag[L.DX_DV_SLICE] >= TACTICAL.vrw**2 * dt * (1 - 1e-12))
    assert np.all(q_diag[L.DX_DV_SLICE] <= TACTICAL.vrw**2 * dt + coupling * 1.001)
    np.testing.assert_allclose(q_diag[L.DX_DTHETA_SLICE], TACTICAL.arw**2 * dt, rtol=1e-6)
    np.testing.assert_allclose(q_diag[L.DX_DB_G_SLICE], TACTICAL.gyro_bias_rw**2 * dt, rtol=1e-12)
    q1, q2 = TCXO.q_cdt, TCXO.q_cddt
    clock = slice(L.DX_DC_DT, L.DX_DC_DDT + 1)
    np.testing.assert_allclose(Qd[clock, clock], [[q1 * dt + q2 * dt**3 / 3, q2 * dt**2 / 2],
                                                  [q2 * dt**2 / 2, q2 * dt]], rtol=1e-12)
    assert Qd[L.DX_DB_LO, L.DX_DB_LO] == pytest.approx(0.04 * dt)


def test_ellipsoid_normal_matches_geodetic_and_is_finite_on_the_axis():
    """The trig-free normal, sin(lat) and height equal those from geodetic_from_ecef (atan2 form)."""
    from leonav.models.gravity import normal_gravity, normal_gravity_sin

    rng = np.random.default_rng(3)
    for _ in range(20):
        lat, lon, h = rng.uniform(-1.5, 1.5), rng.uniform(-math.pi, math.pi), rng.uniform(-500, 9000)
        r = _num(frames.ecef_from_geodetic, lat, lon, h)
        up, sin_lat, h2 = _num(frames.ellipsoid_normal_from_ecef, r)
        lat2, lon2, h3 = _num(frames.geodetic_from_ecef, r)
        ref = [math.cos(lat2) * math.cos(lon2), math.cos(lat2) * math.sin(lon2), math.sin(lat2)]
        np.testing.assert_allclose(up, ref, atol=1e-15)
        assert abs(np.linalg.norm(up) - 1) < 1e-15 and abs(sin_lat - math.sin(lat)) < 1e-12
        assert abs(h2 - h3) < 1e-8 and abs(h2 - h) < 1e-3
        assert float(_num(normal_gravity_sin, sin_lat, h2)) == pytest.approx(float(_num(normal_gravity, lat2, h3)),
                                                                             rel=1e-15)
    # on the polar axis (rho = 0) the normal is finite: straight up, and the height is exact
    up, sin_lat, h = _num(frames.ellipsoid_normal_from_ecef, np.array([0.0, 0.0, 6356752.3142 + 100.0]))
    np.testing.assert_allclose(up, [0, 0, 1], atol=1e-15)
    assert sin_lat == pytest.approx(1.0, abs=1e-15) and h == pytest.approx(100.0, abs=1e-3)
