"""Satellite identification of ridges from predicted Doppler / Doppler-rate curves.

For ridge i (measurement epochs t_k, Doppler d_k with the unknown LO offset, rate a_k)
and candidate satellite s (predicted D_s(t_k), alpha_s(t_k)):
- constant LO offset, closed-form least squares: b = mean_k(d_k - D_s(t_k));
- residuals r_f = d_k - D_s - b (Hz) and r_a = a_k - alpha_s (Hz/s);
- cost J = sqrt( mean(r_f^2)/s_f^2 + mean(r_a^2)/s_a^2 ) / sqrt(2),
  with scales s_f = max(doppler_floor_hz, median sigma_f) and s_a = max(rate_floor_hz_s,
  median sigma_a). The floors stand for what the prediction cannot know exactly (element
  set error, LO drift): J <= 1 means "fits as well as the model can tell".
Assignment: ridges x satellites, solved jointly (scipy linear_sum_assignment) so two ridges
never take one satellite; costs above `max_cost` are forbidden.
Per ridge, the ambiguity ratio is J_second / max(J_best, 1) over all other candidates (both
costs are reported): the best cost is floored at 1 because below that the fit is limited
by the model's own error, not by the measurement. A ridge is *ambiguous* when the ratio is
below `ambiguity_ratio` (1.5): another satellite fits nearly as well, or also within the
model's error (satellites of one launch flying in a train). Such a
ridge keeps its best candidate in the report but is not passed to the filter. A ridge
whose best cost exceeds `max_cost` is *unassociated*, with the reason.
"""
from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import linear_sum_assignment

from leonav_runtime.beacons.doppler import RidgeMeasurements
from leonav_runtime.beacons.predict import Predictions


@dataclasses.dataclass
class AssociationConfig:
    doppler_floor_hz: float = 20.0
    rate_floor_hz_s: float = 2.0
    max_cost: float = 5.0
    ambiguity_ratio: float = 1.5
    min_epochs: int = 2


@dataclasses.dataclass
class Association:
    ridge_id: int
    status: str                 # associated | ambiguous | unassociated
    reason: str
    sat_row: int = -1           # row in Predictions (best candidate), -1 if none
    name: str = ""
    norad_id: int = -1
    cost: float = float("nan")
    second_cost: float = float("nan")
    second_name: str = ""
    second_norad_id: int = -1
    ambiguity_ratio: float = float("nan")
    lo_offset_hz: float = float("nan")
    rms_doppler_hz: float = float("nan")
    rms_rate_hz_s: float = float("nan")
    doppler_residual_hz: np.ndarray | None = None  # per epoch, after offset removal
    rate_residual_hz_s: np.ndarray | None = None   # per epoch: measured - predicted


def candidate_costs(meas: RidgeMeasurements, pred: Predictions, cfg: AssociationConfig):
    """(cost (nsat,), offset (nsat,), r_f (nsat, nk), r_a (nsat, nk)) of one ridge."""
    D, A = pred.at(meas.t_s)
    diff = meas.doppler_hz[None, :] - D
    b = diff.mean(axis=1)
    r_f = diff - b[:, None]
    r_a = meas.rate_hz_s[None, :] - A
    s_f = max(cfg.doppler_floor_hz, float(np.median(meas.sigma_doppler_hz)))
    s_a = max(cfg.rate_floor_hz_s, float(np.median(meas.sigma_rate_hz_s)))
    cost = np.sqrt((np.mean(r_f**2, axis=1) / s_f**2 + np.mean(r_a**2, axis=1) / s_a**2) / 2)
    return cost, b, r_f, r_a


def associate(measurements: list[RidgeMeasurements], pred: Predictions,
              cfg: AssociationConfig | None = None) -> list[Association]:
    """Assign ridges to satellites jointly; every ridge gets a status and a reason."""
    cfg = cfg or AssociationConfig()
    nsat = len(pred.names)
    out: dict[int, Association] = {}
    usable, costs, details = [], [], {}
    for m in measurements:
        if m.t_s.size < cfg.min_epochs:
            out[m.ridge_id] = Association(m.ridge_id, "unassociated",
                                          f"only {m.t_s.size} measurement epoch(s); need {cfg.min_epochs}")
            continue
        if nsat == 0:
            out[m.ridge_id] = Association(m.ridge_id, "unassociated", "no satellite above the elevation mask")
            continue
        c, b, r_f, r_a = candidate_costs(m, pred, cfg)
        usable.append(m)
        costs.append(c)
        details[m.ridge_id] = (c, b, r_f, r_a)
    if usable:
        C = np.vstack(costs)
        big = 1e6
        Cg = np.where(C <= cfg.max_cost, C, big)
        rows, cols = linear_sum_assignment(Cg)
        assigned = {usable[i].ridge_id: j for i, j in zip(rows, cols) if Cg[i, j] < big}
        for i, m in enumerate(usable):
            c, b, r_f, r_a = details[m.ridge_id]
            order = np.argsort(c)
            best = int(order[0])
            j = assigned.get(m.ridge_id)
            if j is None:
                reason = (f"best candidate {pred.names[best]} ({pred.norad_ids[best]}) has cost {c[best]:.2f} > "
                          f"max_cost {cfg.max_cost:g} (rms rate residual {np.sqrt(np.mean(r_a[best]**2)):.1f} Hz/s)")
                if c[best] <= cfg.max_cost:
                    reason = (f"its only fitting satellites were taken by ridges that fit them better "
                              f"(best {pred.names[best]}, cost {c[best]:.2f})")
                a = Association(m.ridge_id, "unassociated", reason, cost=float(c[best]),
                                name=pred.names[best], norad_id=int(pred.norad_ids[best]))
                a.sat_row = -1
                out[m.ridge_id] = a
                continue
            others = np.delete(np.arange(nsat), j)
            k = int(others[np.argmin(c[others])]) if others.size else -1
            c2 = float(c[k]) if k >= 0 else float("inf")
            ratio = c2 / max(c[j], 1.0)
            ambiguous = ratio < cfg.ambiguity_ratio
            status = "ambiguous" if ambiguous else "associated"
            reason = (f"{pred.names[k]} ({pred.norad_ids[k]}) fits nearly as well: cost {c2:.2f} vs {c[j]:.2f}"
                      if ambiguous else "")
            out[m.ridge_id] = Association(
                m.ridge_id, status, reason, j, pred.names[j], int(pred.norad_ids[j]), float(c[j]), c2,
                pred.names[k] if k >= 0 else "", int(pred.norad_ids[k]) if k >= 0 else -1, float(ratio),
                float(b[j]), float(np.sqrt(np.mean(r_f[j] ** 2))), float(np.sqrt(np.mean(r_a[j] ** 2))),
                r_f[j], r_a[j])
    return [out[m.ridge_id] for m in measurements]
