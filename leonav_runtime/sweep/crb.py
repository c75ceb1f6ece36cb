"""Snapshot Cramér-Rao bound of a static receiver's position from Starlink observables.

The snapshot CRB stacks, over every epoch of the window and every selected satellite,
the Jacobian of the observable with respect to the receiver's ENU position, obtained by
central finite differences of the generated measurement model `h` (not its generated
Jacobian), and inverts the Fisher information:
    J = sum_i g_i g_i^T / sigma^2,   g_i = d h_i / d p_enu,   CRB = J^-1.
It bounds a receiver that knows everything but its position and does not move. With a
vague position prior, tight priors elsewhere and negligible process noise, the PCRB of
the filter must equal it (`pcrb_static`), an independent check of the PCRB recursion.
"""
from __future__ import annotations

import numpy as np

from leonav_runtime.core import navfuncs
from leonav_runtime.simulation import simulate

FD_STEP_M = 1.0  # central-difference step; the models are smooth on this scale


def position_gradients(setup: simulate.Setup, nav: navfuncs.NavFunctions, kind_name: str,
                       rows: np.ndarray) -> np.ndarray:
    """(len(rows), 3) d h / d p_enu at the truth, by central differences of the generated h."""
    s = setup.series[kind_name]
    L = nav.layout
    k = np.rint(s.t_s[rows] * setup.scn.imu_rate_hz).astype(int)
    grads = np.empty((rows.size, L.X_P_ENU_SIZE))
    for j, (row, kk) in enumerate(zip(rows, k)):
        for axis in range(L.X_P_ENU_SIZE):
            xp, xm = setup.x_true[kk].copy(), setup.x_true[kk].copy()
            xp[L.X_P_ENU + axis] += FD_STEP_M
            xm[L.X_P_ENU + axis] -= FD_STEP_M
            grads[j, axis] = (nav.h(s.kind, xp, s.aux[row])[0] - nav.h(s.kind, xm, s.aux[row])[0]) / (2 * FD_STEP_M)
    return grads


def snapshot_crb(setup: simulate.Setup, nav: navfuncs.NavFunctions, count: int,
                 kind_name: str = "doppler_rate", sigma: float | None = None) -> np.ndarray:
    """3 x 3 position CRB (m^2, ENU) from `count` satellites over the whole window."""
    rows = simulate.selected_rows(setup, kind_name, count)
    sigma = sigma if sigma is not None else simulate.noise_sigma(setup.scn, kind_name)
    g = position_gradients(setup, nav, kind_name, rows)
    return np.linalg.inv(g.T @ g / sigma**2)


def pcrb_static(setup: simulate.Setup, nav: navfuncs.NavFunctions, count: int, mode: str = "leo-alpha+imu",
                vague_position_var_m2: float = 1e10, tight_var: float = 1e-14,
                tiny_noise: float = 1e-12) -> np.ndarray:
    """Final 3 x 3 position block of the PCRB with a vague position prior, tight priors on
    every other state and negligible process noise (IMU, clock, LO)."""
    L = nav.layout
    params = setup.params.copy()
    for off in (L.P_VRW, L.P_ARW, L.P_ACC_BIAS_RW, L.P_GYRO_BIAS_RW, L.P_Q_CDT, L.P_Q_CDDT, L.P_Q_BLO):
        params[off] = tiny_noise
    B0 = np.eye(L.NDX) * tight_var
    dp = L.DX_DP_SLICE
    B0[dp, dp] = np.eye(L.DX_DP_SIZE) * vague_position_var_m2
    from leonav_runtime.sweep.montecarlo import pcrb_on_truth

    _, res = pcrb_on_truth(setup, nav, mode, count, B0=B0, params=params)
    return res.B_nav[-1][dp, dp]  # B_nav's rows are those of dx[DX_NAV9_SLICE], which starts at dp
