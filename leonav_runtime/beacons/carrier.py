"""Carrier tracking of beacon tones: accumulated carrier phase per epoch, with lock and slips.

For each tone, an aided mix-down (`carrier_front`: the element-set predicted Doppler plus
the tone's offset minus the LO estimate, as baseband frequency) feeds an FLL-assisted
third-order PLL (`carrier_loop`, where the loop design is documented). Per epoch
(`epoch_s`, 0.1 s) the tracker gives:

- phase_cycles: accumulated carrier phase at baseband, Phi_aid(t) + NCO phase / 2 pi
  (cycles; it rises with the baseband frequency, so its change is -delta rho / lambda plus
  the LO and clock terms); NaN when not locked. Its integer part is arbitrary per arc;
- sigma_cycles: sqrt(B_n / (C/N0) (1 + 1 / (2 T C/N0))) / 2 pi with the loop's own noise
  bandwidth (`carrier_loop.noise_bandwidth_hz`) and the estimated C/N0 (thermal only);
- locked: every prompt of the epoch's interval in lock, and none between the last good
  lock statistic (d >= 3) and a declared loss, nor a lock window before it (the detector
  needs ~0.1-0.3 s to see a fade; those prompts are taken back);
- slip: the epoch starts a new arc after the first: the loop relocked after a loss, or the
  step detector found a jump in the locked NCO phase (least-squares step of a cubic plus
  step fitted over +-`slip_half_s`, |step| > `slip_threshold_cycles`). The phase is
  continuous (one ambiguity) within an arc;
- cn0_dbhz over +-`cn0_window_s` / 2; freq_hz and rate_hz_s (baseband frequency and its
  rate) from a cubic fit of the tracked phase over +-`fit_half_s`, when all of it is
  locked in one arc (a quadratic's slope would carry jerk h^2 / 10 of bias: 0.2 Hz at
  30 Hz/s^2 of jerk over +-0.25 s).

Times are receiver times, s since the capture's first sample (the sample clock's error
stays in them, as in the capture).
"""
from __future__ import annotations

import dataclasses
from typing import Iterable, Sequence

import numpy as np

from leonav_runtime.beacons.carrier_front import Aiding, FrontEnd, SUB_RATE_HZ, validate_rate
from leonav_runtime.beacons.carrier_loop import LOCK, LOST, Loop, LoopConfig, noise_bandwidth_hz


@dataclasses.dataclass
class CarrierConfig:
    loop: LoopConfig = dataclasses.field(default_factory=LoopConfig)
    epoch_s: float = 0.1
    fit_half_s: float = 0.25
    slip_half_s: float = 0.3
    slip_threshold_cycles: float = 0.4   # 4.4 sigma of the step statistic in lock at 20 dB-Hz
    cn0_window_s: float = 1.0
    sub_rate_hz: float = SUB_RATE_HZ


@dataclasses.dataclass
class CarrierTrack:
    """Per-epoch output of one tone (see module doc for each field)."""

    label: str
    t_s: np.ndarray
    phase_cycles: np.ndarray
    sigma_cycles: np.ndarray
    locked: np.ndarray
    slip: np.ndarray
    arc: np.ndarray
    cn0_dbhz: np.ndarray
    freq_hz: np.ndarray
    rate_hz_s: np.ndarray
    counts: dict

    def locked_fraction(self, after_first_lock: bool = True) -> float:
        """Share of epochs in lock (from the first locked epoch on, by default)."""
        lk = self.locked
        if after_first_lock and lk.any():
            lk = lk[int(np.argmax(lk)):]
        return float(lk.mean()) if lk.size else 0.0


class _Tone:
    """One tone's front end and loop. k0: the decimated sample its first fed sample starts (a tone
    that joins a streaming capture later: the caller feeds from sample k0 * M on)."""

    def __init__(self, aiding: Aiding, fs: float, cfg: CarrierConfig, k0: int = 0):
        self.front = FrontEnd(aiding, fs, cfg.sub_rate_hz)
        self.front.k = k0
        self.loop = Loop(cfg.loop, self.front.sub_rate_hz)
        self.phi_aid, self.f_aid = [], []
        self.k_first = k0   # decimated sample of phi_aid's first value
        self.buf = np.zeros(0, np.complex64)
        self.buf0 = k0      # index of buf[0] among all decimated samples
        self.pos = k0       # next decimated sample the loop will read

    def trim(self, k_keep: int) -> None:
        """Forget the prompts starting before decimated sample k_keep and the aiding before it
        (a streaming tracker's memory stays bounded)."""
        rec = self.loop.rec
        n = int(np.searchsorted(np.asarray(rec["i0"]), k_keep)) if rec["i0"] else 0
        for v in rec.values():
            del v[:n]
        cut = max(0, min(k_keep, self.front.k) - self.k_first)
        if cut and self.phi_aid:
            self.phi_aid = [np.concatenate(self.phi_aid)[cut:]]
            self.f_aid = [np.concatenate(self.f_aid)[cut:]]
            self.k_first += cut

    def feed(self, x: np.ndarray) -> None:
        y, ph, f = self.front.feed(x)
        self.phi_aid.append(ph)
        self.f_aid.append(f)
        self.buf = np.concatenate([self.buf, y])
        stop = self.loop.run(self.buf, self.pos - self.buf0, self.buf0)
        self.pos = self.buf0 + stop
        keep = int(round(self.loop.cfg.acq_s * self.loop.rate)) + self.loop.p   # acquisition looks ahead
        cut = max(0, min(stop, self.buf.size - keep))
        self.buf, self.buf0 = self.buf[cut:], self.buf0 + cut


def track_tones(blocks: Iterable[np.ndarray], sample_rate_hz: float, aidings: Sequence[Aiding],
                duration_s: float, cfg: CarrierConfig | None = None) -> list[CarrierTrack]:
    """Track every tone of `aidings` through the capture given as sample blocks (complex,
    any block size); one pass over the samples, shared by all tones."""
    cfg = cfg or CarrierConfig()
    validate_rate(sample_rate_hz, cfg.loop.acq_range_hz, cfg.sub_rate_hz)
    for a in aidings:
        a.check_covers(duration_s, sample_rate_hz)
    tones = [_Tone(a, sample_rate_hz, cfg) for a in aidings]
    for x in blocks:
        for t in tones:
            t.feed(x)
    return [_epochs(t, cfg) for t in tones]


def _retro_unlock(mode: np.ndarray, d: np.ndarray, window: int, good_d: float) -> np.ndarray:
    """Lock per prompt, taking back, before each declared loss, the prompts since the lock
    statistic was last good (>= `good_d`) and one window more (its sum spans a window)."""
    ok = mode == LOCK
    loss = np.nonzero((mode[1:] == LOST) & (mode[:-1] == LOCK))[0] + 1
    for j in loss:
        k = j - 1
        while k > 0 and ok[k] and d[k] < good_d:
            k -= 1
        ok[max(0, k - window):j] = False
    return ok


def step_statistic(phase_cycles: np.ndarray, half: int) -> np.ndarray:
    """Least-squares step (cycles) between samples i-1 and i of a cubic-plus-step fit over
    [i - half, i + half); NaN where the window leaves the series."""
    tau = np.arange(-half, half, dtype=float) / half
    a = np.column_stack([np.ones_like(tau), tau, tau**2, tau**3, (tau >= 0).astype(float)])
    w = np.linalg.pinv(a)[-1]
    out = np.full(phase_cycles.size, np.nan)
    if phase_cycles.size >= 2 * half:
        # correlation: s[i] = sum_j w[j] p[i - half + j]
        out[half:phase_cycles.size - half + 1] = np.correlate(phase_cycles, w, mode="valid")
    return out


def _step_slips(res_cycles: np.ndarray, ok: np.ndarray, arc: np.ndarray, half: int, thr: float) -> np.ndarray:
    """Prompt indices where the step detector fires (largest |step| within +-half)."""
    s = step_statistic(res_cycles, half)
    n = s.size
    same = np.zeros(n, bool)
    if n >= 2 * half:   # window [i - half, i + half) all locked, one arc at both ends
        bad = np.concatenate([[0], np.cumsum(~ok)])
        i = np.arange(half, n - half + 1)
        same[i] = (bad[i + half] - bad[i - half] == 0) & (arc[i - half] == arc[i + half - 1])
    cand = np.nonzero(same & (np.abs(np.nan_to_num(s)) > thr))[0]
    out = []
    for i in cand:
        lo, hi = max(0, i - half), min(n, i + half)
        if abs(s[i]) >= np.nanmax(np.abs(s[lo:hi])):
            out.append(i)
    return np.asarray(out, int)


def _epochs(tone: _Tone, cfg: CarrierConfig, e_first: int = 1, e_last: int | None = None) -> CarrierTrack:
    """The tone's epochs e_first..e_last (epoch e ends at e * epoch_s; default: all its prompts give)."""
    loop, front = tone.loop, tone.front
    rec = {k: np.asarray(v) for k, v in loop.rec.items()}
    phi_aid = np.concatenate(tone.phi_aid) if tone.phi_aid else np.zeros(0)
    f_aid = np.concatenate(tone.f_aid) if tone.f_aid else np.zeros(0)
    dt_sub = front.m / front.fs
    n_p = rec["i0"].size
    label = front.aiding.label
    counts = {"prompts": int(n_p), "acquisitions": loop.acquisitions, "bn_hz": noise_bandwidth_hz(loop.cfg),
              "t_coh_s": loop.t, "sub_rate_hz": front.sub_rate_hz, "weak_loop": loop.weak,
              "cn0_acquisition_dbhz": loop.cn0_acq_dbhz}
    if n_p == 0:
        z = np.zeros(0)
        return CarrierTrack(label, z, z, z, np.zeros(0, bool), np.zeros(0, bool), np.zeros(0, int), z, z, z,
                            {**counts, "epochs": 0, "losses": 0, "slips": 0, "step_slips": 0})
    t0 = rec["i0"] * dt_sub
    T = loop.t
    centre = t0 + 0.5 * T

    def aid_phase(t):
        k = np.clip((t / dt_sub).astype(int) - tone.k_first, 0, phi_aid.size - 1)
        return phi_aid[k] + f_aid[k] * (t - (k + tone.k_first) * dt_sub)

    ok = _retro_unlock(rec["mode"], rec["d"], loop.cfg.lock_window, loop.cfg.lock_on_d)
    arc = rec["arc"]
    res = (rec["phi"] + rec["w"] * 0.5 * T) / (2 * np.pi)            # NCO residual phase at prompt centres
    total_c = aid_phase(centre) + res
    half = max(4, int(round(cfg.slip_half_s / T)))
    steps = _step_slips(res, ok, arc, half, cfg.slip_threshold_cycles)
    last = int(np.floor((t0[-1] + T) / cfg.epoch_s + 1e-9))
    e_last = last if e_last is None else min(e_last, last)
    n_ep = max(0, e_last - e_first + 1)
    t_e = cfg.epoch_s * np.arange(e_first, e_first + n_ep)
    out = {k: np.full(n_ep, np.nan) for k in ("phase", "sigma", "cn0", "freq", "rate")}
    locked = np.zeros(n_ep, bool)
    slip = np.zeros(n_ep, bool)
    arcs = np.full(n_ep, -1, int)
    bn = counts["bn_hz"]
    step_t = t0[steps] if steps.size else np.zeros(0)
    prev_loop_arc, cur_arc = None, -1
    def window(t_lo, t_hi):   # prompts whose centres lie in [t_lo, t_hi] (centres increase)
        return slice(int(np.searchsorted(centre, t_lo, "left")), int(np.searchsorted(centre, t_hi, "right")))

    p2 = np.abs(rec["z"]) ** 2
    for e, te in enumerate(t_e):
        i = int(np.searchsorted(t0, te, side="right") - 1)
        span = slice(int(np.searchsorted(t0 + T, te - cfg.epoch_s, "right")), int(np.searchsorted(t0, te, "left")))
        win = window(te - 0.5 * cfg.cn0_window_s, te + 0.5 * cfg.cn0_window_s)
        use = rec["mode"][win] != 0
        if use.any():
            n2 = np.median(rec["noise"][win][use]) * loop.p
            ps = np.mean(p2[win][use]) - n2
            if ps > 0 and n2 > 0:
                out["cn0"][e] = 10 * np.log10(ps / n2 / T)
        if not (span.stop > span.start and ok[span].all() and np.unique(arc[span]).size == 1):
            continue
        locked[e] = True
        la = int(arc[span][0])
        jump = bool(np.any((step_t > te - cfg.epoch_s) & (step_t <= te)))
        if prev_loop_arc is not None and (la != prev_loop_arc or jump):
            slip[e] = True
        if prev_loop_arc is None or slip[e] or not locked[e - 1]:
            cur_arc += 1
        prev_loop_arc = la
        arcs[e] = cur_arc
        out["phase"][e] = aid_phase(np.array([te]))[0] + (rec["phi"][i] + rec["w"][i] * (te - t0[i])) / (2 * np.pi)
        cn0 = 10 ** (out["cn0"][e] / 10) if np.isfinite(out["cn0"][e]) else np.nan
        out["sigma"][e] = np.sqrt(bn / cn0 * (1 + 1 / (2 * T * cn0))) / (2 * np.pi)
        fit = window(te - cfg.fit_half_s, te + cfg.fit_half_s)
        if fit.stop - fit.start >= 5 and ok[fit].all() and np.unique(arc[fit]).size == 1:
            c = np.polyfit(centre[fit] - te, total_c[fit] - total_c[fit][0], 3)   # cubic: a quadratic's
            out["freq"][e], out["rate"][e] = c[2], 2 * c[1]      # slope takes jerk h^2/10 (0.2 Hz) too
    losses = int(np.sum((rec["mode"][1:] == LOST) & (rec["mode"][:-1] == LOCK)))
    counts.update(epochs=n_ep, locked_epochs=int(locked.sum()), losses=losses, slips=int(slip.sum()),
                  step_slips=int(steps.size))
    return CarrierTrack(label, t_e, out["phase"], out["sigma"], locked, slip, arcs, out["cn0"], out["freq"],
                        out["rate"], counts)
