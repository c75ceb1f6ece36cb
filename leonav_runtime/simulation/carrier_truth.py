"""The simulator's truth of a time-differenced carrier phase, built without the filter's model.

The filter predicts the phase change over (t - T, t] from a second-order expansion at t with a
first-order light-time rate (models/measurements/carrier_phase.py). The truth here is what the
tones do: the received phase at t is the phase the satellite sent at t - tau, with tau the exact
light time, solved by iteration with the satellite moved back along its ECEF Taylor expansion
and the Earth's rotation during the flight applied as a rotation (not the Sagnac series); the
change is the difference of the two ranges, each at its own receiver and satellite state; the
front end's offset is the true LO frequency (as the SDR measures it) integrated over the
interval, and the sample clock scales the geometry's part (truth of s_clk and b_lo from the
trial's sensor-error draws).
"""
from __future__ import annotations

import numpy as np

from leonav_runtime.core import model
from leonav_runtime.gen import constants as K

C = K.C_LIGHT_MPS
OMEGA = K.OMEGA_IE_RADPS
LIGHT_TIME_TOL_S = 1e-15   # a few nanometres of range


def light_time_range(r_S: np.ndarray, v_S: np.ndarray, a_S: np.ndarray, r_U: np.ndarray) -> np.ndarray:
    """c tau (m) of signals received at r_U (n, 3, ECEF at reception) from satellites whose
    ECEF state at reception is (r_S, v_S, a_S) (n, 3 each: m, m/s, m/s^2): the fixed point of
    c tau = |Rz(w tau) r_S(t - tau) - r_U| with r_S(t - tau) its Taylor expansion (the satellite's
    jerk over ~3 ms moves it by nanometres) and Rz the Earth's rotation during the flight."""
    tau = np.linalg.norm(r_S - r_U, axis=1) / C
    for _ in range(10):
        r_tx = r_S - v_S * tau[:, None] + 0.5 * a_S * tau[:, None] ** 2
        c, s = np.cos(OMEGA * tau), np.sin(OMEGA * tau)
        rot = np.stack([c * r_tx[:, 0] + s * r_tx[:, 1], -s * r_tx[:, 0] + c * r_tx[:, 1], r_tx[:, 2]], axis=1)
        new = np.linalg.norm(rot - r_U, axis=1) / C
        done = np.max(np.abs(new - tau), initial=0.0) < LIGHT_TIME_TOL_S
        tau = new
        if done:
            break
    return C * tau


def differenced_rows(rows: list) -> tuple[list, np.ndarray, np.ndarray]:
    """The rows (simulate.py's tuples) whose satellite was also tracked at the previous epoch,
    with that epoch's IMU sample index and satellite state (n, 9): a phase difference needs both
    ends, so a satellite's first epoch gives none."""
    epochs = sorted({r[0] for r in rows})
    prev_of = dict(zip(epochs[1:], epochs[:-1]))
    at = {(r[0], r[2]): r[3] for r in rows}
    keep, k_prev, sat_prev = [], [], []
    for r in rows:
        kp = prev_of.get(r[0])
        if kp is not None and (kp, r[2]) in at:
            keep.append(r)
            k_prev.append(kp)
            sat_prev.append(at[(kp, r[2])])
    return keep, np.array(k_prev, int), np.array(sat_prev, float).reshape(len(keep), 9)


def geometric_cycles(f_c_hz: float, sat: np.ndarray, sat_prev: np.ndarray, r_U: np.ndarray,
                     r_U_prev: np.ndarray) -> np.ndarray:
    """-(f_c/c) (c tau(t) - c tau(t - T)) (cycles) per row: the phase change the geometry makes.
    sat, sat_prev (n, 9): satellite r, v, a (ECEF) at both ends; r_U, r_U_prev (n, 3) the
    receiver (ECEF) at both ends."""
    rho = light_time_range(sat[:, 0:3], sat[:, 3:6], sat[:, 6:9], r_U)
    rho_prev = light_time_range(sat_prev[:, 0:3], sat_prev[:, 3:6], sat_prev[:, 6:9], r_U_prev)
    return -(f_c_hz / C) * (rho - rho_prev)


def trial_values(z_geometry: np.ndarray, k: np.ndarray, k_prev: np.ndarray, errors: dict[str, np.ndarray],
                 x_base: np.ndarray, dt_imu: float) -> np.ndarray:
    """(B, n) true phase changes (cycles) of B trials: (1 - s_clk(t)) geometry + the integral of
    b_lo over the interval, s_clk and b_lo from the trial's sensor-error truth `errors`
    ((B, samples, 1) each; absent: the base truth x_base's value), the integral by the trapezoid
    over the IMU samples k_prev .. k (the truth's own resolution)."""
    def truth_of(name):
        b = model.state_block(name)
        if name in errors:
            return errors[name][:, :, 0]
        return x_base[None, :, b.offset]
    b_lo, s_clk = truth_of("b_lo"), truth_of("s_clk")
    cum = np.concatenate([np.zeros((b_lo.shape[0], 1)), np.cumsum(0.5 * (b_lo[:, 1:] + b_lo[:, :-1]), axis=1)],
                         axis=1) * dt_imu
    lo_cycles = cum[:, k] - cum[:, k_prev]
    return (1.0 - s_clk[:, k]) * z_geometry[None, :] + lo_cycles
