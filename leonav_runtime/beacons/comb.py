"""Grouping of tone ridges into per-satellite combs, and their combined measurement.

Each Starlink channel carries ~9 CW tones spaced `COMB_SPACING_HZ` apart (one on the
channel centre, up to 4 each side; see shared/data/starlink/STARLINK_KU_FREQUENCIES.md).
The tones of one satellite share its Doppler curve, so their ridges are *parallel* and
offset by a multiple of the spacing. (The Doppler of tone k is (1 + k*spacing/f_c) times
the centre's: at most 31 ppm, 8 Hz on 260 kHz and 0.12 Hz/s on 4 kHz/s, inside the
tolerances below and ignored.)

Pairing rule for ridges i, j overlapping in time (Doppler d, rate a on common epochs):
    k = round(median(d_j - d_i) / spacing), 1 <= |k| <= 2 * max_tones_per_side
    |d_j - d_i - k*spacing| <= tol at every common epoch, tol = tol_hz + tol_ppm * |k| * spacing
        (+ 4 sigma of the Doppler fits),
    |mean(a_j - a_i)| <= 4 sigma of the rate difference + rate_tol_hz_s.
Pairs are merged best first (union-find with relative tone indices); a merge is refused
when it would put two ridges overlapping in time on the same tone, or spread a comb over
more than 2 * max_tones_per_side + 1 tones.

Combined measurement of a comb at each epoch: inverse-variance weighted mean of its tones'
rates (sigma = 1/sqrt(sum 1/sigma_k^2)) and of their Doppler referred to the comb's lowest
tone (d_k - rel_k * spacing).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from leonav_runtime.beacons.doppler import RidgeMeasurements
from leonav_runtime.gen.constants import COMB_SPACING_HZ



@dataclasses.dataclass
class CombConfig:
    spacing_hz: float = COMB_SPACING_HZ
    max_tones_per_side: int = 4       # 9 tones: centre +/- 4
    tol_hz: float = 40.0              # offset tolerance (fit noise, Doppler scaling of outer tones)
    tol_ppm: float = 100.0            # ... plus this fraction of the offset (SDR clock, spacing value)
    rate_tol_hz_s: float = 1.0        # rate agreement beyond 4 sigma
    enabled: bool = True


@dataclasses.dataclass
class Comb:
    """Ridges of one satellite's tone comb and their combined measurement.

    `rel_index[k]` is the tone index of ridge `ridge_ids[k]` relative to the comb's lowest
    tone (0 .. width). `measurement.doppler_hz` refers to that lowest tone; its ridge_id is
    the carrier ridge (most epochs). `n_tones[e]` counts the tones averaged at epoch e.
    """

    comb_id: int
    ridge_ids: list[int]
    rel_index: list[int]
    measurement: RidgeMeasurements
    n_tones: np.ndarray

    @property
    def width(self) -> int:
        return int(max(self.rel_index))

    @property
    def carrier_ridge_id(self) -> int:
        return int(self.measurement.ridge_id)

    @property
    def tones(self) -> int:
        """Distinct tones seen (fragments of one tone count once)."""
        return len(set(self.rel_index))


def _key(t: np.ndarray) -> np.ndarray:
    return np.round(np.asarray(t) * 1e6).astype(np.int64)  # epochs compared to the microsecond


def pair_offset(mi: RidgeMeasurements, mj: RidgeMeasurements, cfg: CombConfig) -> tuple[int, float] | None:
    """(k, |miss| in Hz) when ridge j looks like ridge i shifted by k tones, else None."""
    ii, jj, dt = _match_epochs(mi.t_s, mj.t_s)
    if ii.size == 0:
        return None
    jerk = np.gradient(mj.rate_hz_s, mj.t_s) if mj.t_s.size > 1 else np.zeros(1)
    dd = mj.doppler_hz[jj] + mj.rate_hz_s[jj] * dt + 0.5 * jerk[jj] * dt**2 - mi.doppler_hz[ii]
    k = int(np.round(np.median(dd) / cfg.spacing_hz))
    if not 1 <= abs(k) <= 2 * cfg.max_tones_per_side:
        return None
    miss = dd - k * cfg.spacing_hz
    sig_d = np.hypot(mi.sigma_doppler_hz[ii], mj.sigma_doppler_hz[jj])
    tol = cfg.tol_hz + cfg.tol_ppm * 1e-6 * abs(k) * cfg.spacing_hz
    if np.any(np.abs(miss) > tol + 4 * sig_d):
        return None
    da = mj.rate_hz_s[jj] + jerk[jj] * dt - mi.rate_hz_s[ii]
    sig_a = np.sqrt(np.mean(mi.sigma_rate_hz_s[ii] ** 2 + mj.sigma_rate_hz_s[jj] ** 2) / da.size)
    if abs(float(np.mean(da))) > 4 * sig_a + cfg.rate_tol_hz_s:
        return None
    return k, float(np.median(np.abs(miss)))


def _match_epochs(ti: np.ndarray, tj: np.ndarray, max_dt_s: float = 1.5):
    """Indices (ii, jj) and t_i - t_j of each epoch of i paired with the nearest epoch of j.

    Epochs on the common grid match exactly; a short ridge's single mid-span epoch is
    compared with its neighbour's Doppler moved by rate * dt + jerk * dt^2 / 2 (jerk from
    the neighbour's rates; a ridge of one epoch has none: then the error is jerk * dt^2 / 2,
    up to ~30 Hz for dt = 1 s near zenith).
    """
    pos = np.clip(np.searchsorted(tj, ti), 1, max(tj.size - 1, 1)) if tj.size > 1 else np.zeros(ti.size, int)
    if tj.size > 1:
        pos = np.where(np.abs(tj[pos - 1] - ti) <= np.abs(tj[pos] - ti), pos - 1, pos)
    dt = ti - tj[pos]
    ok = np.abs(dt) <= max_dt_s
    return np.nonzero(ok)[0], pos[ok], dt[ok]


def _overlap(a: RidgeMeasurements, b: RidgeMeasurements) -> bool:
    return bool(a.t_s.size and b.t_s.size and a.t_s[0] <= b.t_s[-1] and b.t_s[0] <= a.t_s[-1])


def group_combs(measurements: list[RidgeMeasurements], cfg: CombConfig | None = None) -> list[Comb]:
    """Group ridges (with at least one epoch) into combs; a lone ridge is a comb of one tone."""
    cfg = cfg or CombConfig()
    ms = [m for m in measurements if m.t_s.size]
    n = len(ms)
    group = list(range(n))          # group label of each ridge
    rel = [0] * n                   # tone index relative to the group's reference
    edges = []
    if cfg.enabled:
        for i in range(n):
            for j in range(i + 1, n):
                p = pair_offset(ms[i], ms[j], cfg)
                if p is not None:
                    edges.append((p[1], i, j, p[0]))
    max_width = 2 * cfg.max_tones_per_side
    for _, i, j, k in sorted(edges):
        gi, gj = group[i], group[j]
        shift = rel[i] + k - rel[j]   # add to group j's indices to express them in group i's
        if gi == gj:
            continue                  # already placed (consistently or not: the first, best pair wins)
        mem_i = [a for a in range(n) if group[a] == gi]
        mem_j = [b for b in range(n) if group[b] == gj]
        idx = [rel[a] for a in mem_i] + [rel[b] + shift for b in mem_j]
        if max(idx) - min(idx) > max_width:
            continue
        clash = any(rel[a] == rel[b] + shift and _overlap(ms[a], ms[b]) for a in mem_i for b in mem_j)
        if clash:
            continue
        for b in mem_j:
            group[b], rel[b] = gi, rel[b] + shift
    combs = []
    for g in sorted(set(group), key=lambda g: min(ms[a].t_s[0] for a in range(n) if group[a] == g)):
        mem = [a for a in range(n) if group[a] == g]
        lo = min(rel[a] for a in mem)
        members = [(ms[a], rel[a] - lo) for a in mem]
        meas, n_tones = combine(members, cfg.spacing_hz)
        combs.append(Comb(len(combs), [m.ridge_id for m, _ in members], [r for _, r in members], meas, n_tones))
    return combs


def combine(members: list[tuple[RidgeMeasurements, int]], spacing_hz: float = COMB_SPACING_HZ
            ) -> tuple[RidgeMeasurements, np.ndarray]:
    """Inverse-variance combination of the tones of one comb at every epoch (see module doc)."""
    carrier = max(members, key=lambda mr: (mr[0].t_s.size, float(np.median(mr[0].snr_db))))[0]
    if len(members) == 1:
        return carrier, np.ones(carrier.t_s.size, int)
    keys = np.unique(np.concatenate([_key(m.t_s) for m, _ in members]))
    nk = keys.size
    sw_a, swa, sw_d, swd = (np.zeros(nk) for _ in range(4))
    t, npts, snr, ntones = np.zeros(nk), np.zeros(nk, int), np.full(nk, -np.inf), np.zeros(nk, int)
    for m, r in members:
        pos = np.searchsorted(keys, _key(m.t_s))
        wa = 1.0 / np.maximum(m.sigma_rate_hz_s, 1e-9) ** 2   # floor: an exact fit has sigma 0
        wd = 1.0 / np.maximum(m.sigma_doppler_hz, 1e-9) ** 2
        np.add.at(sw_a, pos, wa)
        np.add.at(swa, pos, wa * m.rate_hz_s)
        np.add.at(sw_d, pos, wd)
        np.add.at(swd, pos, wd * (m.doppler_hz - r * spacing_hz))
        t[pos] = m.t_s
        np.add.at(npts, pos, m.n_points)
        np.add.at(ntones, pos, 1)
        snr[pos] = np.maximum(snr[pos], m.snr_db)
    meas = RidgeMeasurements(carrier.ridge_id, t, swd / sw_d, 1 / np.sqrt(sw_d), swa / sw_a, 1 / np.sqrt(sw_a),
                             npts, snr)
    return meas, ntones
