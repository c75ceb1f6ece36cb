"""Satellite identification of ridges from predicted Doppler / Doppler-rate curves.

Ridges are first grouped into combs (`comb.group_combs`: the parallel tones of one
satellite); each comb is associated as one unit with its combined measurement.

Cost of comb c (epochs t_k, Doppler d_k referred to its lowest tone, rate a_k) against
candidate satellite s (predicted D_s(t_k), alpha_s(t_k)), given the common drift b1:
- own offset, closed-form least squares: e = mean_k(d_k - D_s - b1 t_k) (the per-ridge fit,
  used alone as the first guess);
- residuals r_f = d_k - D_s - b1 t_k - e (Hz) and r_a = a_k - alpha_s - b1 (Hz/s);
- LO consistency: dev = wrap(e - b0, spacing), the distance of the comb's own offset to the
  capture's common offset b0 modulo the tone spacing (the comb's tone index is unknown);
- cost J = sqrt( (mean(r_f^2)/s_f^2 + mean(r_a^2)/s_a^2 + dev^2/s_lo^2) / 3 ), or without the
  dev term (and /2) while no common offset is known, with scales s_f = max(doppler_floor_hz,
  median sigma_f), s_a = max(rate_floor_hz_s, median sigma_a) and s_lo = the prediction's
  Doppler uncertainty (lo_floor_hz, and |alpha_s| * prediction_time_sigma_s for an
  along-track timing error of the element set) with the sigma of b0. The floors stand for
  what the prediction cannot know exactly: J <= 1 means "fits as well as the model can tell".
Joint LO fit (alternation): assign (minimum-cost assignment, `assignment`; costs above `max_cost`
forbidden, so two combs never take one satellite); estimate (b0 mod spacing, b1) robustly
from the assigned combs (`lo_fit`), each comb's own b0/b1 leave-one-out from the *other*
combs so it cannot confirm itself; recompute costs; repeat until the assignment is stable.
Per comb, the ambiguity ratio is J_second / max(J_best, 1) over all other candidates (both
costs are reported): the best cost is floored at 1 because below that the fit is limited
by the model's own error, not by the measurement. A comb is *ambiguous* when the ratio is
below `ambiguity_ratio` (1.5): another satellite fits nearly as well, or also within the
model's error (satellites of one launch flying in a train). Such a comb keeps its best
candidate in the report but is not passed to the filter. A comb whose best cost exceeds
`max_cost` is *unassociated*, with the reason. Every ridge of a comb gets its comb's status.

Measurements for the filter (`CaptureAssociation.filter_measurements`): one per associated
comb (keyed by its carrier ridge), the combined rates with the common drift b1 removed when
at least `min_combs_for_drift` combs agree on it (their slopes scatter less than
`max_drift_spread_hz_s`), sigma including the drift's; the Doppler referred to the central
tone. The drift estimate is reported either way (summary.json, measurement CSV).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from leonav_runtime.beacons.assignment import linear_sum_assignment
from leonav_runtime.beacons.comb import Comb, CombConfig, group_combs
from leonav_runtime.beacons.doppler import RidgeMeasurements
from leonav_runtime.beacons.lo_fit import LoEstimate, circular_offset, comb_residual, robust_mean, wrap
from leonav_runtime.beacons.predict import Predictions


@dataclasses.dataclass
class AssociationConfig:
    doppler_floor_hz: float = 20.0
    rate_floor_hz_s: float = 2.0
    max_cost: float = 5.0
    ambiguity_ratio: float = 1.5
    min_epochs: int = 2
    joint_lo: bool = True                 # False: the per-ridge offset only (the first guess)
    lo_floor_hz: float = 50.0             # Doppler prediction floor for the LO consistency term
    prediction_time_sigma_s: float = 0.1  # element-set along-track error as a time (~750 m)
    drift_floor_hz_s: float = 0.02
    max_iterations: int = 6
    remove_drift: bool = True
    min_combs_for_drift: int = 2
    max_drift_spread_hz_s: float = 1.0
    comb: CombConfig = dataclasses.field(default_factory=CombConfig)


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
    lo_offset_hz: float = float("nan")   # the comb's own offset at t=0, referred to the central tone when known
    rms_doppler_hz: float = float("nan")
    rms_rate_hz_s: float = float("nan")
    doppler_residual_hz: np.ndarray | None = None  # per epoch, after offset removal
    rate_residual_hz_s: np.ndarray | None = None   # per epoch: measured (drift removed if so) - predicted
    comb_id: int = -1
    comb_tones: int = 1         # distinct tones in the comb
    tone_index: int | None = None  # channel tone index (0 = centre) when the comb is associated
    carrier: bool = True        # this ridge carries the comb's combined measurement
    lo_deviation_hz: float = float("nan")  # comb offset minus the common offset (mod spacing)


@dataclasses.dataclass
class CaptureAssociation:
    """Per-ridge associations, the combs, the common LO estimate and the filter's measurements."""

    associations: list[Association]
    combs: list[Comb]
    lo: LoEstimate
    filter_measurements: dict[int, RidgeMeasurements]  # carrier ridge id -> measurement (associated combs)


@dataclasses.dataclass
class _CombCosts:
    cost: np.ndarray        # (nsat,)
    intercept: np.ndarray   # (nsat,) own offset at t = 0 (lowest tone), drift removed
    r_f: np.ndarray         # (nsat, nk)
    r_a: np.ndarray         # (nsat, nk)
    dev: np.ndarray         # (nsat,) wrapped distance to the common offset (nan without one)


def _comb_costs(m: RidgeMeasurements, D: np.ndarray, A: np.ndarray, cfg: AssociationConfig, drift: float,
                b0: float | None, sigma_b0: float) -> _CombCosts:
    """Costs of one comb against all candidates (see module doc)."""
    r = m.doppler_hz[None, :] - D - drift * m.t_s[None, :]
    e = r.mean(axis=1)
    r_f = r - e[:, None]
    r_a = m.rate_hz_s[None, :] - A - drift
    s_f = max(cfg.doppler_floor_hz, float(np.median(m.sigma_doppler_hz)))
    s_a = max(cfg.rate_floor_hz_s, float(np.median(m.sigma_rate_hz_s)))
    terms = np.mean(r_f**2, axis=1) / s_f**2 + np.mean(r_a**2, axis=1) / s_a**2
    if b0 is None:
        return _CombCosts(np.sqrt(terms / 2), e, r_f, r_a, np.full(e.size, np.nan))
    s_lo = np.sqrt(cfg.lo_floor_hz**2 + (cfg.prediction_time_sigma_s * np.sqrt(np.mean(A**2, axis=1))) ** 2
                   + sigma_b0**2 + float(np.median(m.sigma_doppler_hz)) ** 2 / m.t_s.size)
    dev = wrap(e - b0, cfg.comb.spacing_hz)
    return _CombCosts(np.sqrt((terms + (dev / s_lo) ** 2) / 3), e, r_f, r_a, dev)


def _residual(m: RidgeMeasurements, D: np.ndarray, A: np.ndarray, cfg: AssociationConfig):
    return comb_residual(m.t_s, m.doppler_hz - D, m.sigma_doppler_hz, m.rate_hz_s - A, m.sigma_rate_hz_s, A,
                         cfg.prediction_time_sigma_s, cfg.lo_floor_hz, cfg.drift_floor_hz_s)


def _common(res: list, spacing: float) -> tuple[float, float | None, float]:
    """(drift, b0 mod spacing or None, sigma b0) from the residual summaries of some combs."""
    if not res:
        return 0.0, None, 0.0
    slopes = [(r.slope_hz_s, r.sigma_slope_hz_s) for r in res if np.isfinite(r.sigma_slope_hz_s)]
    drift = robust_mean(*map(np.asarray, zip(*slopes)))[0] if slopes else 0.0
    b0, sig, _ = circular_offset(np.asarray([r.intercept(drift) for r in res]),
                                 np.asarray([r.sigma_offset_hz for r in res]), spacing)
    return drift, b0, sig


def _assign(C: np.ndarray, max_cost: float) -> dict[int, int]:
    big = 1e6
    Cg = np.where(C <= max_cost, C, big)
    rows, cols = linear_sum_assignment(Cg)
    return {int(i): int(j) for i, j in zip(rows, cols) if Cg[i, j] < big}


def _tone_indices(intercepts: dict[int, float], widths: dict[int, int], b0_mod: float, spacing: float,
                  per_side: int) -> tuple[float, dict[int, int], bool]:
    """Absolute offset and each comb's lowest-tone index (see LoEstimate): (b0, {comb: n}, pinned)."""
    n0 = {c: int(np.round((e - b0_mod) / spacing)) for c, e in intercepts.items()}
    lo = max(n0[c] + widths[c] - per_side for c in n0)
    hi = min(n0[c] + per_side for c in n0)
    pinned = lo == hi
    if lo > hi:  # no shift puts every comb inside the channel: take the least-bad centring
        lo, hi = min(n0.values()) - per_side, max(n0.values()) + per_side
    shifts = np.arange(lo, hi + 1)
    score = [(sum(abs(n0[c] - m + widths[c] / 2) for c in n0), abs(b0_mod + m * spacing)) for m in shifts]
    m = int(shifts[min(range(len(shifts)), key=lambda i: score[i])])
    return b0_mod + m * spacing, {c: n - m for c, n in n0.items()}, pinned


def associate_capture(measurements: list[RidgeMeasurements], pred: Predictions,
                      cfg: AssociationConfig | None = None) -> CaptureAssociation:
    """Group ridges into combs, assign combs to satellites with a joint LO offset and drift."""
    cfg = cfg or AssociationConfig()
    spacing = cfg.comb.spacing_hz
    nsat = len(pred.names)
    out: dict[int, Association] = {}
    for m in measurements:
        if m.t_s.size == 0:
            out[m.ridge_id] = Association(m.ridge_id, "unassociated", "no measurement epoch (ridge too short)")
    combs = group_combs(measurements, cfg.comb)
    usable: list[Comb] = []
    for c in combs:
        n_ep = c.measurement.t_s.size
        reason = (f"only {n_ep} measurement epoch(s); need {cfg.min_epochs}" if n_ep < cfg.min_epochs else
                  "no satellite above the elevation mask" if nsat == 0 else "")
        if reason:
            for rid, rel in zip(c.ridge_ids, c.rel_index):
                out[rid] = Association(rid, "unassociated", reason, comb_id=c.comb_id, comb_tones=c.tones,
                                       carrier=rid == c.carrier_ridge_id)
        else:
            usable.append(c)
    lo = LoEstimate(ambiguity_hz=spacing)
    filt: dict[int, RidgeMeasurements] = {}
    if usable:
        curves = [pred.at(c.measurement.t_s) for c in usable]
        nc = len(usable)
        drift_c, b0_c, sig_c = np.zeros(nc), [None] * nc, np.zeros(nc)
        assign: dict[int, int] | None = None
        for _ in range(max(1, cfg.max_iterations)):
            costs = [_comb_costs(c.measurement, D, A, cfg, drift_c[i], b0_c[i], sig_c[i])
                     for i, (c, (D, A)) in enumerate(zip(usable, curves))]
            new = _assign(np.vstack([k.cost for k in costs]), cfg.max_cost)
            if not cfg.joint_lo or new == assign:
                break
            assign = new
            resid = {i: _residual(usable[i].measurement, curves[i][0][j], curves[i][1][j], cfg)
                     for i, j in assign.items()}
            for i in range(nc):  # leave-one-out: a comb's own fit never sets its reference
                drift_c[i], b0_c[i], sig_c[i] = _common([r for o, r in resid.items() if o != i], spacing)
        assign = new
        status = {}
        for i, c in enumerate(usable):
            k = costs[i]
            j = assign.get(i)
            if j is None:
                status[i] = ("unassociated", None, -1, np.inf)
                continue
            others = np.delete(np.arange(nsat), j)
            s2 = int(others[np.argmin(k.cost[others])]) if others.size else -1
            c2 = float(k.cost[s2]) if s2 >= 0 else float("inf")
            ratio = c2 / max(k.cost[j], 1.0)
            status[i] = ("ambiguous" if ratio < cfg.ambiguity_ratio else "associated", j, s2, ratio)
        # the capture's common LO from the associated combs (all of them now, no leave-one-out)
        good = [i for i in status if status[i][0] == "associated"]
        resid = {i: _residual(usable[i].measurement, curves[i][0][status[i][1]], curves[i][1][status[i][1]], cfg)
                 for i in good}
        n_idx: dict[int, int] = {}
        if good:
            lo, n_idx = _lo_estimate(resid, {i: usable[i].width for i in good}, cfg)
        drift_out = lo.drift_hz_s if lo.drift_removed else 0.0
        for i, c in enumerate(usable):
            st, j, s2, ratio = status[i]
            k = costs[i]
            best = int(np.argmin(k.cost))
            if st == "unassociated":
                reason = (f"best candidate {pred.names[best]} ({pred.norad_ids[best]}) has cost {k.cost[best]:.2f} > "
                          f"max_cost {cfg.max_cost:g} (rms rate residual {np.sqrt(np.mean(k.r_a[best]**2)):.1f} Hz/s)")
                if k.cost[best] <= cfg.max_cost:
                    reason = (f"its only fitting satellites were taken by combs that fit them better "
                              f"(best {pred.names[best]}, cost {k.cost[best]:.2f})")
                for rid in c.ridge_ids:
                    out[rid] = Association(rid, "unassociated", reason, cost=float(k.cost[best]),
                                           name=pred.names[best], norad_id=int(pred.norad_ids[best]),
                                           comb_id=c.comb_id, comb_tones=c.tones, carrier=rid == c.carrier_ridge_id)
                continue
            reason = (f"{pred.names[s2]} ({pred.norad_ids[s2]}) fits nearly as well: cost {k.cost[s2]:.2f} vs "
                      f"{k.cost[j]:.2f}" if st == "ambiguous" else "")
            n_low = n_idx.get(i)
            D, A = curves[i][0][j], curves[i][1][j]
            m = c.measurement
            # residuals against the drift that goes out with the measurements
            r_a = m.rate_hz_s - A - drift_out
            own = float(np.mean(m.doppler_hz - D - lo.drift_hz_s * m.t_s)) - (n_low or 0) * spacing
            for rid, rel in zip(c.ridge_ids, c.rel_index):
                carrier = rid == c.carrier_ridge_id
                rr = r_a
                if not carrier:
                    mm = next(x for x in measurements if x.ridge_id == rid)
                    rr = mm.rate_hz_s - pred.at(mm.t_s)[1][j] - drift_out
                out[rid] = Association(
                    rid, st, reason, j, pred.names[j], int(pred.norad_ids[j]), float(k.cost[j]),
                    float(k.cost[s2]) if s2 >= 0 else float("inf"), pred.names[s2] if s2 >= 0 else "",
                    int(pred.norad_ids[s2]) if s2 >= 0 else -1, float(ratio), own,
                    float(np.sqrt(np.mean(k.r_f[j] ** 2))), float(np.sqrt(np.mean(r_a**2))), k.r_f[j], rr,
                    c.comb_id, c.tones, None if n_low is None else n_low + rel, carrier, float(k.dev[j]))
            if st == "associated":
                filt[c.carrier_ridge_id] = _filter_measurement(m, lo, (n_low or 0) * spacing)
    return CaptureAssociation([out[m.ridge_id] for m in measurements], combs, lo, filt)


def _lo_estimate(resid: dict, widths: dict[int, int], cfg: AssociationConfig) -> tuple[LoEstimate, dict[int, int]]:
    """Common offset and drift from the associated combs' residual summaries; also {comb: lowest tone index}."""
    spacing = cfg.comb.spacing_hz
    lo = LoEstimate(ambiguity_hz=spacing, n_combs=len(resid))
    slopes = np.asarray([(r.slope_hz_s, r.sigma_slope_hz_s) for r in resid.values()
                         if np.isfinite(r.sigma_slope_hz_s)]).reshape(-1, 2)
    notes = []
    if slopes.shape[0]:
        lo.drift_hz_s, lo.sigma_drift_hz_s = robust_mean(slopes[:, 0], slopes[:, 1])
        spread = float(np.sqrt(np.mean((slopes[:, 0] - lo.drift_hz_s) ** 2))) if slopes.shape[0] > 1 else np.inf
        if not cfg.remove_drift:
            notes.append("drift removal switched off")
        elif slopes.shape[0] < cfg.min_combs_for_drift:
            notes.append(f"drift not removed: {slopes.shape[0]} comb(s) with a slope, need {cfg.min_combs_for_drift} "
                         f"(one satellite's own residual would be absorbed)")
        elif spread > cfg.max_drift_spread_hz_s:
            notes.append(f"drift not removed: the combs' slopes scatter by {spread:.2f} Hz/s > "
                         f"{cfg.max_drift_spread_hz_s:g} (moving receiver or stale element sets?)")
        else:
            lo.drift_removed = True
    ids = list(resid)
    b0_mod, sig, _ = circular_offset(np.asarray([resid[i].intercept(lo.drift_hz_s) for i in ids]),
                                     np.asarray([resid[i].sigma_offset_hz for i in ids]), spacing)
    b0, n_idx, pinned = _tone_indices({i: resid[i].intercept(lo.drift_hz_s) for i in ids}, widths, b0_mod, spacing,
                                  cfg.comb.max_tones_per_side)
    lo.offset_hz, lo.sigma_offset_hz, lo.pinned = float(b0), float(sig), bool(pinned)
    if not pinned:
        notes.append(f"offset known modulo the tone spacing {spacing:g} Hz (no comb shows all its tones): "
                     f"index chosen to centre the combs on the channel")
    lo.note = "; ".join(notes)
    return lo, n_idx


def _filter_measurement(m: RidgeMeasurements, lo: LoEstimate, tone_shift_hz: float) -> RidgeMeasurements:
    """The comb's measurement as sent to the filter: drift removed (if so), Doppler of the central tone."""
    rate, sig = m.rate_hz_s, m.sigma_rate_hz_s
    if lo.drift_removed:
        rate = rate - lo.drift_hz_s
        sig = np.hypot(sig, lo.sigma_drift_hz_s)
    return dataclasses.replace(m, doppler_hz=m.doppler_hz - tone_shift_hz, rate_hz_s=rate, sigma_rate_hz_s=sig)


def associate(measurements: list[RidgeMeasurements], pred: Predictions,
              cfg: AssociationConfig | None = None) -> list[Association]:
    """Per-ridge associations (see `associate_capture`), in the order of `measurements`."""
    return associate_capture(measurements, pred, cfg).associations
