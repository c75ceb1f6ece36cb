"""Common LO offset and drift of one capture from the combs' Doppler residuals.

Every tone of a capture goes through the same LNB and SDR, so measured minus predicted
Doppler of comb c (assigned to satellite s) is, to the prediction's error,
    d_c(t) - D_s(t) = b0 + b1 * t + n_c * spacing,
with b(t) = b0 + b1 t the common offset (Hz, = minus the LNB LO error; b1 its drift, Hz/s)
and n_c the unknown channel index of the comb's lowest tone. The drift shows as a bias
b1 on every measured Doppler *rate*.

- b1: Huber-weighted mean over combs of each comb's drift estimate: the slope of d - D
  (least squares over its epochs, own intercept) or the mean rate residual a - alpha,
  whichever is more precise (they come from the same ridge points, so they are not
  averaged): the rate mean wins on short combs, the slope on long ones (its sigma falls
  as T^-1.5). A comb's sigma adds what the prediction cannot know: an along-track timing
  error sigma_t of the element set moves D by alpha * sigma_t and the rate by jerk * sigma_t.
- b0: known only modulo the tone spacing from Doppler alone. Circular robust estimate:
  each comb's intercept e_c is tried as the centre, the one with the smallest capped
  (at 3 sigma) sum of squared wrapped residuals wins, then refined by the weighted mean
  of its inliers' wrapped residuals.
"""
from __future__ import annotations

import dataclasses

import numpy as np


def wrap(x: np.ndarray | float, period: float) -> np.ndarray | float:
    """x reduced to [-period/2, period/2)."""
    return x - period * np.floor(np.asarray(x) / period + 0.5)


def robust_mean(values: np.ndarray, sigmas: np.ndarray, k: float = 2.0, iters: int = 8) -> tuple[float, float]:
    """Robust weighted mean of values with 1-sigma `sigmas`; (mean, sigma of the mean).

    Weighted median, Huber iterations, then the weighted mean of the values within 3 sigma
    of it. The sigma is the formal one, inflated by the normalized scatter when that exceeds 1.
    """
    v, s = np.asarray(values, float), np.maximum(np.asarray(sigmas, float), 1e-12)
    w = 1.0 / s**2
    order = np.argsort(v)
    cw = np.cumsum(w[order])
    m = float(v[order][np.searchsorted(cw, 0.5 * cw[-1])])  # weighted median as the start
    for _ in range(iters):
        u = np.abs(v - m) / s
        h = np.minimum(1.0, k / np.maximum(u, 1e-12))
        m = float(np.sum(w * h * v) / np.sum(w * h))
    # Huber still leans towards gross outliers: drop values beyond 3 sigma, plain weighted mean of the rest
    inl = np.abs(v - m) <= 3 * s
    if inl.any():
        m = float(np.sum(w[inl] * v[inl]) / np.sum(w[inl]))
    else:
        inl = np.ones(v.size, bool)
    sig = 1.0 / np.sqrt(np.sum(w[inl]))
    if inl.sum() > 1:
        chi2 = float(np.sum(w[inl] * (v[inl] - m) ** 2)) / (inl.sum() - 1)
        sig *= max(1.0, np.sqrt(chi2))
    return m, float(sig)


def circular_offset(values: np.ndarray, sigmas: np.ndarray, period: float) -> tuple[float, float, np.ndarray]:
    """Common value of `values` modulo `period`: (centre in [-period/2, period/2), sigma, inlier mask)."""
    v, s = np.asarray(values, float), np.maximum(np.asarray(sigmas, float), 1e-12)
    best, best_score = 0.0, np.inf
    for c in v:
        u = wrap(v - c, period) / s
        score = float(np.sum(np.minimum(u**2, 9.0)))
        if score < best_score:
            best, best_score = float(c), score
    r = wrap(v - best, period)
    inl = np.abs(r) <= 3 * s
    w = 1.0 / s[inl] ** 2
    centre = float(wrap(best + np.sum(w * r[inl]) / np.sum(w), period))
    return centre, float(1.0 / np.sqrt(np.sum(w))), inl


@dataclasses.dataclass
class CombResidual:
    """Doppler residual summary of one comb against one satellite (for the LO fit)."""

    slope_hz_s: float        # drift seen by this comb (slope of d - D, or mean rate residual)
    sigma_slope_hz_s: float  # incl. the prediction's jerk * sigma_t
    mean_t_s: float          # mean epoch
    mean_resid_hz: float     # mean of d - D (at mean_t_s)
    sigma_offset_hz: float   # what the prediction cannot know: alpha * sigma_t (+ floor)

    def intercept(self, drift_hz_s: float) -> float:
        """Offset at t = 0 given a common drift."""
        return self.mean_resid_hz - drift_hz_s * self.mean_t_s


def comb_residual(t_s: np.ndarray, resid_hz: np.ndarray, sigma_d_hz: np.ndarray, rate_resid_hz_s: np.ndarray,
                  sigma_rate_hz_s: np.ndarray, rate_pred_hz_s: np.ndarray, time_sigma_s: float,
                  offset_floor_hz: float, drift_floor_hz_s: float) -> CombResidual:
    """Drift estimate and mean Doppler residual of one comb (d - D in Hz, a - alpha in Hz/s)."""
    tm = float(np.mean(t_s))
    tau = t_s - tm
    stt = float(tau @ tau)
    r_mean = float(np.mean(resid_hz))
    sig_d = float(np.median(sigma_d_hz))
    if stt > 0 and t_s.size >= 2:
        slope = float(tau @ (resid_hz - r_mean) / stt)
        sig_fit = sig_d / np.sqrt(stt)
        # neighbouring epochs' fit windows overlap by half: their rates are correlated (factor sqrt 2)
        sig_rate = float(np.sqrt(2 * np.mean(sigma_rate_hz_s**2) / t_s.size))
        if sig_rate < sig_fit:
            slope, sig_fit = float(np.mean(rate_resid_hz_s)), sig_rate
        jerk = float(np.polyfit(t_s, rate_pred_hz_s, 1)[0])
        sig_slope = float(np.sqrt(sig_fit**2 + (jerk * time_sigma_s) ** 2 + drift_floor_hz_s**2))
    else:
        slope, sig_slope = 0.0, np.inf  # a single epoch tells nothing about the drift
    sig_off = float(np.hypot(offset_floor_hz, time_sigma_s * np.sqrt(np.mean(rate_pred_hz_s**2))))
    return CombResidual(slope, sig_slope, tm, r_mean, float(np.hypot(sig_off, sig_d / np.sqrt(t_s.size))))


@dataclasses.dataclass
class LoEstimate:
    """Common offset b(t) = offset_hz + drift_hz_s * t of measured minus predicted Doppler.

    b = -(LNB LO error), referred to the channel's central tone. `pinned` is False when no
    comb shows its full tone set: the offset is then known modulo `ambiguity_hz` (the tone
    spacing) and the index is chosen so the combs sit as centred on the channel as possible.
    """

    offset_hz: float = float("nan")
    sigma_offset_hz: float = float("nan")
    drift_hz_s: float = 0.0
    sigma_drift_hz_s: float = float("nan")
    n_combs: int = 0
    pinned: bool = False
    ambiguity_hz: float = float("nan")
    drift_removed: bool = False
    note: str = ""

    def at(self, t_s: np.ndarray | float) -> np.ndarray | float:
        return self.offset_hz + self.drift_hz_s * np.asarray(t_s)

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)
