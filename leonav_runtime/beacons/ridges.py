"""Tone detection in STFT slices and tracking of simultaneous ridges.

Detection: per slice, a bin is a tone candidate when its power exceeds the slice's noise
floor `median + k*MAD` and is a local maximum. For noise-only bins (exponential power of
mean mu) the threshold is mu*(ln 2 + k ln(phi)) = mu*(0.693 + 0.481 k): k_detect = 25 gives
12.7 mu, a per-bin false-alarm probability of 3e-6 (about 0.05 false peaks per slice of
16k bins), used to start ridges; k_track is used inside the gate of
an existing ridge, where a false alarm is unlikely and a weak tone is worth keeping;
k_track = 10 (5.5 mu, 4e-3 per bin, ~3% per 7-bin gate and slice).

Tracking: each ridge predicts its next frequency with its current rate (straight-line
fit over its last second) and looks for a local maximum within a gate of `gate_bins` bins
plus the rate uncertainty times the time since its last point: the strongest while the
ridge is young, the one nearest the prediction once its rate is fitted (narrower gate),
so two tones crossing at different rates keep their identities. Peaks are
shared out strongest ridge first; a ridge missing for `max_gap_s` ends. Ridges shorter
than `min_duration_s` are discarded (counted) as noise. Fragments of one tone broken by a
crossing or fade are joined when one extrapolates onto the other.

Sub-bin frequency: quadratic interpolation of the log magnitude over the peak bin and its
two neighbours (Gaussian interpolation).

Cost on hostile input (a noise-free full-scale tone fills the band with quantization
spurs: thousands of peaks per slice): each ridge finds its gate and each peak its side
lobes by binary search over the sorted peaks, at most `max_active` ridges are tracked at
once (further births are refused and counted in `TrackStats.births_refused`), and joining
looks, for each fragment, only at fragments starting within `join_gap_s` after its end,
so it is near-linear in the number of fragments (it was cubic: 4,007 fragments ran for
more than 20 CPU-minutes). More than `max_fragments` fragments: the shortest are dropped
and counted (`TrackStats.fragments_dropped`). Ridge points are kept as packed doubles.
"""
from __future__ import annotations

import dataclasses
from array import array
from bisect import bisect_left, bisect_right


import numpy as np

from leonav_runtime.beacons.waterfall import SpectrumBlock


@dataclasses.dataclass
class TrackerConfig:
    k_detect: float = 25.0       # start threshold, MADs above the median
    k_track: float = 10.0        # continuation threshold inside a gate
    gate_bins: float = 3.0       # gate half-width (bins) before the rate term, young ridge
    gate_bins_confirmed: float = 1.5  # ... once its rate is fitted (prediction good to ~0.1 bin)
    rate_sigma_young_hz_s: float = 5000.0  # rate uncertainty of a ridge with few points
    rate_sigma_hz_s: float = 300.0         # rate uncertainty once the rate is fitted
    rate_fit_s: float = 1.0      # recent span used for the running rate
    max_gap_s: float = 0.5       # a ridge unseen this long ends
    min_duration_s: float = 1.0  # shorter ridges are discarded as noise
    exclusion_bins: int = 6      # a weaker peak this close to a stronger one is a side lobe
    join_gap_s: float = 3.0      # largest gap bridged when joining fragments
    join_tol_hz: float = 150.0   # largest extrapolation miss when joining
    confirm_points: int = 8      # a ridge with fewer points must be seen in consecutive slices
    young_max_gap_slices: float = 2.5  # ... i.e. at most this many hops since its last point
    min_fill: float = 0.5        # kept ridges are seen in at least this fraction of their slices
    max_jitter_bins: float = 0.3  # median |residual| from a smooth fit, in bins (noise tracks hop)
    max_active: int = 512        # ridges tracked at once (9 tones x the few dozen satellites above the mask)
    max_fragments: int = 20000   # fragments kept for joining; beyond, the shortest are dropped (counted)


@dataclasses.dataclass
class Ridge:
    """One tracked tone: times (s since capture start), baseband frequency (Hz), SNR (dB/bin)."""

    t_s: np.ndarray
    f_hz: np.ndarray
    snr_db: np.ndarray
    ridge_id: int = -1

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0]) if self.t_s.size else 0.0


@dataclasses.dataclass
class TrackStats:
    slices: int = 0
    births: int = 0
    discarded_short: int = 0
    discarded_noise: int = 0     # too sparse or too jittery to be a tone
    joined: int = 0
    births_refused: int = 0      # peaks not started as ridges because max_active ridges were tracked
    fragments_dropped: int = 0   # shortest fragments dropped beyond max_fragments

    def notes(self) -> list[str]:
        """Sentences for the summary when a safety cap was reached (empty otherwise)."""
        out = []
        if self.births_refused:
            out.append(f"{self.births_refused} candidate peaks were not tracked: the tracker was at its "
                       "limit of simultaneous ridges (TrackerConfig.max_active); is the band full of spurs "
                       "(a strong interferer, an overloaded SDR)?")
        if self.fragments_dropped:
            out.append(f"{self.fragments_dropped} shortest ridge fragments were dropped before joining "
                       "(TrackerConfig.max_fragments)")
        return out


class _Track:
    __slots__ = ("t", "f", "snr", "rate", "n_fit", "snr_avg")

    def __init__(self, t: float, f: float, snr: float):
        self.t, self.f, self.snr = array("d", [t]), array("d", [f]), array("d", [snr])
        self.rate, self.n_fit, self.snr_avg = 0.0, 0, snr

    def add(self, t: float, f: float, snr: float, span_s: float) -> None:
        self.t.append(t)
        self.f.append(f)
        self.snr.append(snr)
        self.snr_avg += 0.2 * (snr - self.snr_avg)
        if len(self.t) < 16 or len(self.t) % 4 == 0:  # the rate changes slowly: refit every 4th point
            self.refit_rate(span_s)

    def refit_rate(self, span_s: float) -> None:
        # the points of the last `span_s` among the last 256: the times are slice times, which
        # ascend, so those points are a suffix
        t = self.t
        n = len(t)
        i0 = bisect_left(t, t[-1] - span_s, max(0, n - 256))
        m = n - i0
        if m >= 5:
            tt = np.frombuffer(t[i0:], dtype=np.float64)
            ff = np.frombuffer(self.f[i0:], dtype=np.float64)
            # add.reduce / m is ndarray.mean's own sum and division, without its Python wrapper
            tt = tt - np.add.reduce(tt) / m
            self.rate = float(np.dot(tt, ff - np.add.reduce(ff) / m) / np.dot(tt, tt))
            self.n_fit = m


def _local_maxima(p: np.ndarray, thr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rows, columns) in row-major order of the interior bins of `p` (slices x bins) that are
    above their row's `thr`, not below the bin before and above the bin after: the threshold
    first, since it leaves a few per thousand bins to compare with their neighbours."""
    nb = p.shape[1]
    flat = p.reshape(-1)
    i = np.flatnonzero(p > thr[:, None])
    col = i % nb
    i = i[(col > 0) & (col < nb - 1)]
    v = flat[i]
    i = i[(v >= flat[i - 1]) & (v > flat[i + 1])]
    return np.divmod(i, nb)


def _take_side_lobes(taken: list[bool], pk: list[int], k: int, excl: int) -> None:
    """Mark as taken every peak whose bin in `pk` (ascending) is within `excl` bins of bin k."""
    for i in range(bisect_left(pk, k - excl), bisect_right(pk, k + excl)):
        taken[i] = True


def interpolate_peak(power_row: np.ndarray, k: int) -> float:
    """Sub-bin offset (in bins, within +/-0.5) of a peak at bin k from its log magnitude."""
    if k <= 0 or k >= power_row.size - 1:
        return 0.0
    a, b, c = np.log(power_row[k - 1: k + 2].astype(np.float64) + 1e-30)
    den = a - 2 * b + c
    if den >= 0:
        return 0.0
    return float(np.clip(0.5 * (a - c) / den, -0.5, 0.5))


def _peak_offsets(power: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """`interpolate_peak(power[r], c)` for every interior peak (r, c), vectorized (bins)."""
    a, b, c = (np.log(power[rows, cols + d].astype(np.float64) + 1e-30) for d in (-1, 0, 1))
    den = a - 2 * b + c
    with np.errstate(divide="ignore", invalid="ignore"):
        off = np.clip(0.5 * (a - c) / den, -0.5, 0.5)
    return np.where(den < 0, off, 0.0)


class RidgeTracker:
    """Streaming multi-ridge tracker; feed `SpectrumBlock`s, then call `finish()`."""

    def __init__(self, f_hz: np.ndarray, cfg: TrackerConfig | None = None, hop_s: float | None = None):
        self.cfg = cfg or TrackerConfig()
        self.hop_s = hop_s  # slice spacing; set from the first block when None
        self.f_hz = f_hz
        self.df = float(f_hz[1] - f_hz[0])
        self.active: list[_Track] = []
        self.done: list[_Track] = []
        self.stats = TrackStats()
        self._power_dtype = np.dtype(np.float32)   # of the blocks' power (add_block)

    def add_block(self, blk: SpectrumBlock) -> None:
        cfg = self.cfg
        thr_det = blk.noise_median + cfg.k_detect * blk.noise_mad
        thr_trk = blk.noise_median + cfg.k_track * blk.noise_mad
        p = blk.power
        self._power_dtype = p.dtype   # births are ordered by power in its own precision
        rows, cols = _local_maxima(p, thr_trk)
        if self.hop_s is None and blk.t_s.size > 1:
            self.hop_s = float(blk.t_s[1] - blk.t_s[0])
        # sub-bin frequency, bin frequency, power and SNR of every candidate peak of the block at
        # once, as Python lists the slices take their parts of (the same IEEE values as per-slice
        # NumPy arithmetic, without its call overhead per slice and peak)
        power = p[rows, cols]
        f_peak = (self.f_hz[0] + (cols + _peak_offsets(p, rows, cols)) * self.df).tolist()
        snr_peak = (10 * np.log10(power / blk.noise_mean[rows])).tolist()
        f_bin = (self.f_hz[0] + cols * self.df).tolist()
        strong = np.flatnonzero(power > thr_det[rows])  # peaks that may start a ridge (few)
        bins, power = cols.tolist(), power.tolist()
        starts = np.searchsorted(rows, np.arange(p.shape[0] + 1)).tolist()
        strong_starts = np.searchsorted(strong, starts).tolist()
        strong = strong.tolist()
        t_s = blk.t_s.tolist()
        for s in range(p.shape[0]):
            a, b = starts[s], starts[s + 1]
            births = [i - a for i in strong[strong_starts[s]: strong_starts[s + 1]]]
            self._slice(t_s[s], births, bins[a:b], f_bin[a:b], power[a:b], f_peak[a:b], snr_peak[a:b])
        self.stats.slices += p.shape[0]

    def _slice(self, t: float, strong: list[int], pk: list[int], pf: list[float], power: list[float],
               f_peak: list[float], snr_peak: list[float]) -> None:
        """One slice at `t` (s): its candidate peaks' bins `pk` (ascending), their bin frequencies
        `pf` and interpolated frequencies `f_peak` (Hz), powers and SNRs over the mean noise (dB);
        `strong` (ascending indices into them) are those above the detection threshold."""
        cfg, df = self.cfg, self.df
        # strongest ridges pick first so a weak ridge cannot steal a strong tone
        order = sorted(self.active, key=lambda tr: -tr.snr_avg)
        excl = cfg.exclusion_bins
        # Per ridge only its gate is looked at (binary search over the ascending peaks)
        taken = [False] * len(pk)
        for tr in order:
            if not pk:
                break
            gap = t - tr.t[-1]
            f_pred = tr.f[-1] + tr.rate * gap
            confirmed = tr.n_fit >= cfg.confirm_points
            rate_sig = cfg.rate_sigma_hz_s if confirmed else cfg.rate_sigma_young_hz_s
            half = (cfg.gate_bins_confirmed if confirmed else cfg.gate_bins) * df + rate_sig * gap
            # the gate, widened by a bin, then tested exactly as |pf - f_pred| <= half
            lo = bisect_left(pf, f_pred - half - df)
            hi = bisect_right(pf, f_pred + half + df)
            cand = [i for i in range(lo, hi) if not taken[i] and abs(pf[i] - f_pred) <= half]
            if not cand:
                continue
            if confirmed:  # rate known: the peak nearest the prediction (keeps crossing tones apart)
                best = min(cand, key=lambda i: abs(pf[i] - f_pred))
            else:          # rate unknown yet: the strongest peak in the wide gate
                best = max(cand, key=lambda i: power[i])
            tr.add(t, f_peak[best], snr_peak[best], cfg.rate_fit_s)
            _take_side_lobes(taken, pk, pk[best], excl)
        # births: strong peaks not explained by a ridge, strongest first, side lobes skipped
        free = [i for i in strong if not taken[i]]
        if free:
            self._births(t, free, taken, pk, power, f_peak, snr_peak)
        self._end_ridges(t)

    def _births(self, t: float, free: list[int], taken: list[bool], pk: list[int], power: list[float],
                f_peak: list[float], snr_peak: list[float]) -> None:
        """Start ridges at the peaks `free` (indices into the slice's peaks), strongest first;
        a peak within `exclusion_bins` of one started or refused is its side lobe."""
        cfg = self.cfg
        excl = cfg.exclusion_bins
        room = cfg.max_active - len(self.active)
        fr = np.asarray(free)
        for i in fr[np.argsort(-np.asarray(power, self._power_dtype)[fr])].tolist():
            if taken[i]:
                continue
            if room <= 0:
                self.stats.births_refused += 1
            else:
                self.active.append(_Track(t, f_peak[i], snr_peak[i]))
                self.stats.births += 1
                room -= 1
            _take_side_lobes(taken, pk, pk[i], excl)

    def _end_ridges(self, t: float) -> None:
        """End the ridges not seen for too long at slice time `t` (s)."""
        cfg = self.cfg
        still = []
        young_gap = cfg.young_max_gap_slices * (self.hop_s or 0.0)
        for tr in self.active:
            gap = t - tr.t[-1]
            if len(tr.t) < cfg.confirm_points and gap > young_gap:
                self.stats.discarded_short += 1  # a noise peak that never became a ridge
            elif gap > cfg.max_gap_s:
                if len(tr.t) >= 3:
                    self.done.append(tr)
                else:
                    self.stats.discarded_short += 1
            else:
                still.append(tr)
        self.active = still

    def finish(self) -> list[Ridge]:
        """Close all ridges, join fragments, drop short ones; ridges sorted by start time."""
        tracks = self.done + self.active
        self.active, self.done = [], []
        ridges = [Ridge(np.frombuffer(tr.t, np.float64), np.frombuffer(tr.f, np.float64),
                        np.frombuffer(tr.snr, np.float64)) for tr in tracks if len(tr.t) >= 3]
        self.stats.discarded_short += len(tracks) - len(ridges)
        if len(ridges) > self.cfg.max_fragments:
            longest = sorted(range(len(ridges)), key=lambda i: -ridges[i].t_s.size)[: self.cfg.max_fragments]
            self.stats.fragments_dropped += len(ridges) - len(longest)
            ridges = [ridges[i] for i in sorted(longest)]
        ridges = self._join(sorted(ridges, key=lambda r: r.t_s[0]))
        keep = [r for r in ridges if r.duration_s >= self.cfg.min_duration_s]
        self.stats.discarded_short += len(ridges) - len(keep)
        tones = [r for r in keep if self._looks_like_tone(r)]
        self.stats.discarded_noise += len(keep) - len(tones)
        keep = tones
        for i, r in enumerate(keep):
            r.ridge_id = i
        return keep

    def _looks_like_tone(self, r: Ridge) -> bool:
        """A tone is seen in most slices of its span and follows a smooth curve.

        Smoothness: median absolute residual of cubic fits over 5 s pieces, in bins. A real
        tone stays within a fraction of a bin of such a fit; a noise track hops by bins.
        """
        if self.hop_s:
            fill = r.t_s.size / (1 + r.duration_s / self.hop_s)
            if fill < self.cfg.min_fill:
                return False
        if r.t_s.size < 8:
            return False
        pieces = np.floor((r.t_s - r.t_s[0]) / 5.0)
        res = []
        for k in np.unique(pieces):
            sel = pieces == k
            if sel.sum() >= 8:
                tau = r.t_s[sel] - r.t_s[sel].mean()
                res.append(r.f_hz[sel] - np.polyval(np.polyfit(tau, r.f_hz[sel], 3), tau))
        jitter = np.median(np.abs(np.concatenate(res))) / self.df if res else np.inf
        return bool(jitter <= self.cfg.max_jitter_bins)

    def _join(self, ridges: list[Ridge]) -> list[Ridge]:
        """Join fragments of one tone: a fragment extrapolated over the gap onto another's start.

        Result as the pairwise rule applied until nothing changes (ridges sorted by start: the
        first fragment in that order takes the first matching successor, again and again), at
        near-linear cost: only successors starting within `join_gap_s` after the end are tried
        (binary search over the start times) and they are tested together.
        """
        cfg = self.cfg
        n = len(ridges)
        if n < 2:
            return ridges
        starts = np.array([r.t_s[0] for r in ridges])
        firsts = np.array([r.f_hz[0] for r in ridges])
        alive = np.ones(n, bool)
        out = []
        for i in range(n):
            if not alive[i]:
                continue
            pieces = [ridges[i]]  # joined fragments, concatenated once at the end
            t_first, t_last = ridges[i].t_s[0], ridges[i].t_s[-1]
            while t_last - t_first >= 0.2:
                # successors starting in (t_last, t_last + join_gap_s]: a range of the sorted starts
                # (a little wider than needed against rounding, then tested exactly as before)
                lo = int(np.searchsorted(starts, t_last, "left"))
                hi = int(np.searchsorted(starts, t_last + cfg.join_gap_s + 1e-9 * (1.0 + abs(t_last)), "right"))
                js = np.arange(lo, hi)
                gaps = starts[js] - t_last
                ok = alive[js] & (js != i) & (gaps > 0) & (gaps <= cfg.join_gap_s)
                js, gaps = js[ok], gaps[ok]
                if js.size == 0:
                    break
                tt, ff = _tail(pieces, t_last - 1.0)
                deg = 2 if tt.size >= 20 else 1
                coef = np.polyfit(tt - t_last, ff, deg)
                hit = np.nonzero(np.abs(np.polyval(coef, gaps) - firsts[js]) <= cfg.join_tol_hz)[0]
                if hit.size == 0:
                    break
                j = int(js[hit[0]])
                alive[j] = False
                pieces.append(ridges[j])
                t_last = ridges[j].t_s[-1]
                self.stats.joined += 1
            if len(pieces) == 1:
                out.append(pieces[0])
            else:
                out.append(Ridge(np.concatenate([p.t_s for p in pieces]), np.concatenate([p.f_hz for p in pieces]),
                                 np.concatenate([p.snr_db for p in pieces])))
        return out


def _tail(pieces: list[Ridge], t_from: float) -> tuple[np.ndarray, np.ndarray]:
    """Points with t >= t_from of the concatenation of `pieces` (only the last pieces are touched)."""
    k = len(pieces) - 1
    while k > 0 and pieces[k].t_s[0] >= t_from:
        k -= 1
    t = np.concatenate([p.t_s for p in pieces[k:]]) if k < len(pieces) - 1 else pieces[k].t_s
    f = np.concatenate([p.f_hz for p in pieces[k:]]) if k < len(pieces) - 1 else pieces[k].f_hz
    keep = t >= t_from
    return t[keep], f[keep]
