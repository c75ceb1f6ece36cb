"""Every generated Jacobian (F, each H) equals central finite differences through boxplus."""
from __future__ import annotations

import numpy as np
import pytest

from tests import symbolic
from leonav_runtime.gen import state_layout as L
from leonav_runtime.core.params import build_params
from leonav.models.state import MEASUREMENTS, NDX
from tests.registry_reference import fd_steps, random_state

FNS = symbolic.FNS  # built on first use, once per process
P_VEC = np.array(build_params(np.radians(43.0848638), np.radians(-77.6786127), 170.0,
                             lever_b_m=(0.54, -0.22, 1.16)))   # non-zero: the fix Jacobian's attitude terms


def _state(rng):
    """A random state: every block at its registry magnitude (position several km from the origin)."""
    x = random_state(rng, {"p_enu": 2000.0, "v_enu": 20.0, "b_a": 0.05})
    x[L.X_P_ENU + 2] *= 0.025   # heights of tens of metres
    return x


def _level_at_origin():
    x = np.zeros(L.NX)
    x[L.X_Q_NB] = 1.0
    return x


def _aux(rng, r_sat_m):
    """A satellite at distance ~r_sat_m above the site, and a reference one, ECEF."""
    site = np.array(FNS["leonav_receiver_ecef"](_level_at_origin(), P_VEC)[0]).ravel()
    up = site / np.linalg.norm(site)
    r_s = site + r_sat_m * (up + 0.5 * rng.normal(size=3))
    r_ref = site + r_sat_m * (up + 0.5 * rng.normal(size=3))
    v = rng.normal(size=3) * 7000
    aux = np.zeros(L.NAUX)
    aux[:21] = np.r_[r_s, v, rng.normal(size=3) * 8, r_ref, rng.normal(size=3) * 7000, rng.normal(size=3) * 8,
                     [0.3, -0.2, 9.9]]
    # GNSS block: satellite clock, time of day, both atmosphere terms on, a Galileo signal, and
    # Klobuchar coefficients of the GEONET 0759 nav header (2005-04-02)
    aux[L.AUX_SAT_CLOCK_SLICE] = [1.2e5, 0.03]
    aux[L.AUX_T_SOD], aux[L.AUX_IONO_SCALE], aux[L.AUX_TROPO_SCALE] = 40000.0 + 9000 * rng.random(), 1.0, 1.0
    aux[L.AUX_ISB_SELECT_SLICE] = [1.0, 0.0]
    aux[L.AUX_KLOBUCHAR_SLICE] = [1.118e-08, 1.49e-08, -5.96e-08, -5.96e-08, 8.806e04, 1.638e04, -1.966e05, -1.311e05]
    aux[L.AUX_DT_PHASE] = 0.1   # a 10 Hz carrier-phase difference, the satellite 0.1 s earlier
    aux[L.AUX_R_S_PREV_ECEF_SLICE] = r_s - 0.1 * v
    return aux


def _fd(fun, x, step):
    """Central differences of fun(x [+] dx) [-] ... per error component."""
    boxplus = FNS["leonav_boxplus"]
    cols = []
    for j in range(NDX):
        e = np.zeros(NDX)
        e[j] = step[j]
        cols.append((fun(np.array(boxplus(x, e)).ravel()) - fun(np.array(boxplus(x, -e)).ravel())) / (2 * step[j]))
    return np.array(cols).T


STEP = fd_steps()  # finite-difference step per error-state component (registry)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_F_matches_finite_differences(seed):
    rng = np.random.default_rng(seed)
    x = _state(rng)
    u = np.r_[rng.normal(size=3) * 0.02, rng.normal(size=3) * 0.3 + [0, 0, 0.098]]
    dt = 0.01
    mech, boxminus = FNS["leonav_mech"], FNS["leonav_boxminus"]
    F = np.array(FNS["leonav_predict"](x, np.eye(NDX), u, dt, P_VEC)[2])
    f0 = mech(x, u, dt, P_VEC)
    F_fd = _fd(lambda xx: np.array(boxminus(mech(xx, u, dt, P_VEC), f0)).ravel(), x, STEP)
    np.testing.assert_allclose(F, F_fd, rtol=1e-6, atol=1e-8)
    # and F is far from the identity where the physics says so (catches a zero Jacobian)
    assert abs(F[L.DX_DP, L.DX_DV] - dt) < 1e-6 and np.abs(F[L.DX_DV_SLICE, L.DX_DTHETA_SLICE]).max() > 1e-3


@pytest.mark.parametrize("suffix", [m.suffix for m in MEASUREMENTS])
@pytest.mark.parametrize("seed", [0, 1])
def test_H_matches_finite_differences(suffix, seed):
    rng = np.random.default_rng(seed)
    x = _state(rng)
    aux = _aux(rng, 2.0e7 if "pseudorange" in suffix or "range_rate" in suffix else 6.0e5)
    h = FNS[f"leonav_h_{suffix}"]
    H = np.array(h(x, aux, P_VEC)[1]).ravel()
    H_fd = _fd(lambda xx: float(h(xx, aux, P_VEC)[0]), x, STEP).ravel()
    scale = np.abs(H).max()
    assert scale > 0
    np.testing.assert_allclose(H, H_fd, rtol=1e-5, atol=1e-6 * scale, err_msg=suffix)


def test_update_uses_H_and_Joseph_form():
    """update_k equals the textbook Joseph-form update computed in NumPy from h_k's H."""
    rng = np.random.default_rng(5)
    x, aux = _state(rng), _aux(rng, 6e5)
    A = rng.normal(size=(NDX, NDX))
    P = A @ A.T * 0.1 + np.eye(NDX)
    for suffix in ("doppler_rate", "pos_n", "pseudorange"):
        h, H = FNS[f"leonav_h_{suffix}"](x, aux, P_VEC)
        h, H = float(h), np.array(H)
        z, R = h + 0.7, 0.3
        x_post, P_post, y, S, nis = (np.array(v) for v in FNS[f"leonav_update_{suffix}"](x, P, z, R, aux, P_VEC))
        S_ref = (H @ P @ H.T).item() + R
        K = P @ H.T / S_ref
        I_KH = np.eye(NDX) - K @ H
        P_ref = I_KH @ P @ I_KH.T + K @ K.T * R
        assert y.item() == pytest.approx(0.7, rel=1e-9)
        assert S.item() == pytest.approx(S_ref, rel=1e-12)
        assert nis.item() == pytest.approx(0.49 / S_ref, rel=1e-9)
        np.testing.assert_allclose(P_post, P_ref, rtol=1e-9, atol=1e-12 * np.abs(P_ref).max())
        dx = np.array(FNS["leonav_boxminus"](x_post, x)).ravel()
        np.testing.assert_allclose(dx, K.ravel() * 0.7, rtol=1e-8, atol=1e-14)


def test_trapezoid_factorization_reproduces_F_and_G():
    """predict propagates P through F = T F_pre, G = T G_pre: both products equal the Jacobians."""
    import casadi as ca

    from leonav.models import ekf
    from leonav.models.state import NP, NU, NX

    x, u, dt, p = ca.SX.sym("x", NX), ca.SX.sym("u", NU), ca.SX.sym("dt"), ca.SX.sym("p", NP)
    _, F, G = ekf.nav_jacobians(x, u, dt, p)
    T, F_pre, G_pre = ekf.trapezoid_factors(F, G, dt)
    fn = ca.Function("f", [x, u, dt, p], [F, T @ F_pre, G, T @ G_pre])
    rng = np.random.default_rng(11)
    for _ in range(3):
        xv = _state(rng)
        uv = np.r_[rng.normal(size=3) * 0.02, rng.normal(size=3) * 0.3 + [0, 0, 0.098]]
        dt_s = 0.01 + 0.1 * rng.random()
        F_, TF, G_, TG = (np.array(v) for v in fn(xv, uv, dt_s, P_VEC))
        assert abs(F_[L.DX_DP, L.DX_DV] - dt_s) < 1e-6 and np.abs(G_[L.DX_DP_SLICE]).max() > 1e-4  # dp rows not trivial
        np.testing.assert_allclose(TF, F_, rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(TG, G_, rtol=1e-13, atol=1e-15)


def test_predict_covariance_equals_F_P_Ft_plus_Qd():
    """P_next = F P F^T + Qd from the predict's own F and Qd; of a non-symmetric P only the upper
    triangle is read (models.ekf.upper_mirrored: the lower one may hold anything)."""
    rng = np.random.default_rng(12)
    x = _state(rng)
    u = np.r_[rng.normal(size=3) * 0.02, rng.normal(size=3) * 0.3 + [0, 0, 0.098]]
    A = rng.normal(size=(NDX, NDX))
    S = A @ A.T + np.eye(NDX)
    for P in (S, S + 1e-3 * np.tril(A, -1), S + np.tril(A, -1)):
        _, P_next, F, Qd = (np.array(v) for v in FNS["leonav_predict"](x, P, u, 0.02, P_VEC))
        ref = F @ S @ F.T + Qd
        ref = (ref + ref.T) / 2
        np.testing.assert_allclose(P_next, ref, rtol=1e-12, atol=1e-13 * np.abs(ref).max())
        assert np.array_equal(P_next, P_next.T)
        np.testing.assert_array_equal(Qd, Qd.T)
