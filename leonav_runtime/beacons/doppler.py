"""Doppler trajectory and Doppler-rate from a ridge.

Measured Doppler of ridge points (paper: f_D(t_i) = f_i - f_ref):
    f_D = f_baseband + rf_center - f_tone
where `rf_center` is the RF frequency at baseband 0 Hz (SDR tuning + nominal LNB LO) and
`f_tone` the nominal RF tone frequency (11.325 GHz). It still contains the unknown LNB LO
offset (plus SDR ppm error), which association fits as one constant per ridge.

Doppler rate two ways:
- finite difference of consecutive ridge points, the paper's eq. (5): noisy, kept for
  reference and comparison;
- local quadratic fit f(t) = c0 + c1 (t - t_k) + c2 (t - t_k)^2 over a window centred on
  each measurement epoch t_k: alpha = c1, with sigma from the fit residuals
  (sigma^2 = SSR/(n-3), cov = sigma^2 (A^T A)^-1), after one pass dropping points beyond
  4 robust sigmas (noise peaks taken while the tone faded). The quadratic term absorbs the change of
  rate within the window (up to ~100 Hz/s^2 near zenith), so the rate is unbiased at t_k.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from leonav_runtime.beacons.ridges import Ridge


@dataclasses.dataclass
class RidgeMeasurements:
    """Doppler and Doppler-rate of one ridge at measurement epochs (s since capture start)."""

    ridge_id: int
    t_s: np.ndarray          # epochs
    doppler_hz: np.ndarray   # fitted Doppler at t_s (contains the LO offset)
    sigma_doppler_hz: np.ndarray
    rate_hz_s: np.ndarray    # fitted Doppler rate at t_s
    sigma_rate_hz_s: np.ndarray
    n_points: np.ndarray     # ridge points used per epoch
    snr_db: np.ndarray       # median per-bin SNR in each window


def doppler_trajectory(ridge: Ridge, rf_center_hz: float, f_c_hz: float) -> np.ndarray:
    """Measured Doppler (Hz, LO offset included) of every ridge point."""
    return ridge.f_hz + (rf_center_hz - f_c_hz)


def finite_difference_rate(t_s: np.ndarray, f_hz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Paper eq. (5): (f_{i+1} - f_i) / (t_{i+1} - t_i) at the mid-times."""
    dt = np.diff(t_s)
    return 0.5 * (t_s[1:] + t_s[:-1]), np.diff(f_hz) / dt


def local_poly_fit(t_s: np.ndarray, f_hz: np.ndarray, t_k: float, half_window_s: float,
                   degree: int = 2) -> tuple[float, float, float, float, int] | None:
    """Fit around t_k; returns (f, sigma_f, rate, sigma_rate, n) or None if too few points."""
    sel = np.abs(t_s - t_k) <= half_window_s
    n = int(sel.sum())
    if n < degree + 4:
        return None
    tau, f = t_s[sel] - t_k, f_hz[sel]
    A = np.vander(tau, degree + 1, increasing=True)
    coef, *_ = np.linalg.lstsq(A, f, rcond=None)
    res = f - A @ coef
    # one pass of outlier rejection: a noise peak taken inside the gate when the tone faded
    robust_sigma = 1.4826 * np.median(np.abs(res))
    good = np.abs(res) <= max(4.0 * robust_sigma, 1e-9)
    if (~good).any() and good.sum() >= degree + 4:
        tau, f, A, n = tau[good], f[good], A[good], int(good.sum())
        coef, *_ = np.linalg.lstsq(A, f, rcond=None)
        res = f - A @ coef
    s2 = float(res @ res) / (n - degree - 1)
    cov = s2 * np.linalg.inv(A.T @ A)
    return float(coef[0]), float(np.sqrt(cov[0, 0])), float(coef[1]), float(np.sqrt(cov[1, 1])), n


def ridge_measurements(ridge: Ridge, rf_center_hz: float, f_c_hz: float, interval_s: float = 1.0,
                       half_window_s: float = 1.0, min_fill: float = 0.6) -> RidgeMeasurements:
    """Doppler and Doppler-rate at epochs on the global grid k*interval_s inside the ridge.

    An epoch is kept when its window is covered by the ridge and holds at least
    `min_fill` of the points the ridge's median spacing predicts.
    """
    t, fd = ridge.t_s, doppler_trajectory(ridge, rf_center_hz, f_c_hz)
    step = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    expected = 2 * half_window_s / step
    k0 = np.ceil((t[0] + half_window_s) / interval_s)
    k1 = np.floor((t[-1] - half_window_s) / interval_s)
    rows = []
    for k in np.arange(k0, k1 + 1):
        tk = float(k * interval_s)
        fit = local_poly_fit(t, fd, tk, half_window_s)
        if fit is None or fit[4] < min_fill * expected:
            continue
        sel = np.abs(t - tk) <= half_window_s
        rows.append((tk, *fit, float(np.median(ridge.snr_db[sel]))))
    if not rows and t.size >= 8:
        # ridge shorter than one window: a single epoch at its middle, fitted over all of it
        tk = float(0.5 * (t[0] + t[-1]))
        fit = local_poly_fit(t, fd, tk, 0.5 * (t[-1] - t[0]) + 1e-9)
        if fit is not None:
            rows.append((tk, *fit, float(np.median(ridge.snr_db))))
    a = np.asarray(rows, float).reshape(-1, 7)
    return RidgeMeasurements(ridge.ridge_id, a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 4],
                             a[:, 5].astype(int), a[:, 6])
