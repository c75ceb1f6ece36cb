"""Generated NHC / ZUPT observables and the fix lever arm, against an outside rotation (scipy).

Their Jacobians against finite differences and the C against the symbolic model are in
test_models_jacobians.py and test_codegen_c_agreement.py (parametrized over every
observable, lever arm non-zero there); here: what they predict.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from leonav_runtime.core import navfuncs
from leonav_runtime.gen import state_layout as L
from leonav_runtime.core.params import build_params

LEVER_FLU = (0.54, -0.22, 1.16)


@pytest.fixture(scope="module")
def nav():
    return navfuncs.NavFunctions(params=np.array(build_params(0.79, -1.28, 25.0, lever_b_m=LEVER_FLU)))


def _state(rpy, v_enu, p_enu=(3.0, -2.0, 1.0)):
    x = np.zeros(L.NX)
    x[L.X_P_ENU_SLICE] = p_enu
    x[L.X_V_ENU_SLICE] = v_enu
    # scipy: intrinsic Z-Y-X (yaw, pitch, roll) is C_b_n = Rz Ry Rx, the generated convention
    w = Rotation.from_euler("ZYX", [rpy[2], rpy[1], rpy[0]]).as_quat()   # x y z w
    x[L.X_Q_NB_SLICE] = [w[3], w[0], w[1], w[2]]
    return x


def _h(nav, kind, x):
    return nav.h(kind, x, np.zeros(L.NAUX))


@pytest.mark.parametrize("rpy", [(0.0, 0.0, 0.5), (0.1, -0.05, 2.5), (-0.2, 0.15, -1.2)])
def test_nhc_is_the_body_velocity(nav, rpy):
    C_b_n = Rotation.from_euler("ZYX", [rpy[2], rpy[1], rpy[0]]).as_matrix()
    v_b = np.array([1.3, -0.4, 0.25])          # forward, left, up
    x = _state(rpy, C_b_n @ v_b)
    assert _h(nav, "NHC_Y", x)[0] == pytest.approx(v_b[1], abs=1e-12)
    assert _h(nav, "NHC_Z", x)[0] == pytest.approx(v_b[2], abs=1e-12)
    # driving straight ahead satisfies the constraint exactly, and the constraint then sees heading
    x = _state(rpy, C_b_n @ [2.0, 0.0, 0.0])
    h, H = _h(nav, "NHC_Y", x)
    assert h == pytest.approx(0.0, abs=1e-12) and abs(H[L.DX_DTHETA + 2]) == pytest.approx(2.0, rel=0.05)


def test_zupt_is_the_enu_velocity(nav):
    x = _state((0.1, 0.2, 0.3), [0.3, -0.2, 0.05])
    got = [_h(nav, k, x)[0] for k in ("ZUPT_E", "ZUPT_N", "ZUPT_U")]
    np.testing.assert_allclose(got, [0.3, -0.2, 0.05], atol=1e-15)


@pytest.mark.parametrize("rpy", [(0.0, 0.0, np.pi / 2), (0.12, -0.07, 0.8)])
def test_fix_predicts_the_antenna(nav, rpy):
    x = _state(rpy, [0.0, 0.0, 0.0])
    antenna = x[L.X_P_ENU_SLICE] + Rotation.from_euler("ZYX", [rpy[2], rpy[1], rpy[0]]).as_matrix() @ LEVER_FLU
    got = [_h(nav, k, x)[0] for k in ("POS_E", "POS_N", "POS_U")]
    np.testing.assert_allclose(got, antenna, atol=1e-12)
    if rpy == (0.0, 0.0, np.pi / 2):    # facing North: forward arm points North, left arm points West
        np.testing.assert_allclose(np.subtract(got, x[L.X_P_ENU_SLICE]), [0.22, 0.54, 1.16], atol=1e-12)


def test_no_lever_arm_keeps_the_old_fix_model():
    """Zero lever arm and zero latency: the fix is the IMU position; the only other column is
    the latency's, -v (it multiplies a zero covariance unless a run estimates the latency)."""
    nav0 = navfuncs.NavFunctions(params=np.array(build_params(0.79, -1.28, 25.0)))
    v = [1.0, 2.0, 0.5]
    x = _state((0.3, -0.2, 1.0), v)
    for j, k in enumerate(("POS_E", "POS_N", "POS_U")):
        h, H = _h(nav0, k, x)
        assert h == x[j] and H[L.DX_DP + j] == 1.0 and H[L.DX_DDT_FIX] == -v[j]
        assert np.count_nonzero(H) == 2


def test_fix_latency_looks_back_along_the_motion():
    """A fix dt late is the antenna dt ago: position - v dt, velocity - a dt. Adding a forward
    specific force of 1 m/s^2 (body x facing East) adds that acceleration East."""
    nav0 = navfuncs.NavFunctions(params=np.array(build_params(0.79, -1.28, 25.0)))
    x = _state((0.0, 0.0, 0.0), [3.0, 0.0, 0.0])
    x[L.X_DT_FIX] = 0.1
    aux = np.zeros(L.NAUX)
    assert nav0.h("POS_E", x, aux)[0] == pytest.approx(x[0] - 0.3, abs=1e-12)
    v_e0 = nav0.h("VEL_E", x, aux)[0]
    aux[L.AUX_F_B_SLICE] = [1.0, 0.0, 0.0]
    v_e1 = nav0.h("VEL_E", x, aux)[0]
    assert v_e0 - v_e1 == pytest.approx(0.1 * 1.0, abs=1e-9)


def test_fix_velocity_carries_the_lever_rotation(nav):
    """Turning at w about up with the antenna l ahead and left: the antenna moves at w x l."""
    x = _state((0.0, 0.0, 0.0), [0.0, 0.0, 0.0])
    aux = np.zeros(L.NAUX)
    aux[L.AUX_W_B_SLICE] = [0.0, 0.0, 0.5]
    got = [nav.h(k, x, aux)[0] for k in ("VEL_E", "VEL_N", "VEL_U")]
    np.testing.assert_allclose(got, np.cross([0.0, 0.0, 0.5], LEVER_FLU), atol=1e-12)
