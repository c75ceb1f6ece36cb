"""Carrier tracking on a capture that is still being written: samples in, phase differences out.

The streaming twin of `carrier.track_tones` + `inputs.carrier_phase.phase_differences`: tones
join when the beacon stream has identified them (`start_tone`, from the sample it is at), every
pushed block goes through each tone's aided front end and loop (`carrier._Tone`, the batch
code), and the epochs are made by the batch epoch code (`carrier._epochs`) over a window of
recent prompts. An epoch is final `lag_s` after its time: its lock flag looks back from a loss
declared later (0.1-0.3 s), its C/N0 spans +-0.5 s, its slip test +-0.3 s. Epochs are made
`EVERY_S` at a time (so an epoch comes 1-1.5 s after its time). Each call of `take`
makes the epochs from the last one given (included again, so that the pair across two calls is
differenced inside one window: arcs are numbered per window) up to `t_data - lag_s`, and returns
the new phase differences with `phase_differences`' rules and its break counts. Memory stays
bounded: each tone keeps `keep_s` of prompts and aiding behind its last given epoch.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from leonav_runtime.beacons.carrier import CarrierConfig, _epochs, _Tone
from leonav_runtime.beacons.carrier_front import Aiding, block_factors, validate_rate
from leonav_runtime.inputs.carrier_phase import BREAK_REASONS, phase_differences

LAG_S = 1.0
KEEP_S = 2.0
EVERY_S = 0.5      # epochs are made in batches of at least this much (a call per 0.1 s piece costs 3x the loop)


@dataclasses.dataclass
class StreamedDifference:
    """One phase difference: t_s its end (capture time, s), interval_s, the tone's key (ridge
    number) and satellite, z and 1-sigma (cycles, raw tone phase: not referred to the centre)."""

    t_s: float
    interval_s: float
    key: int
    norad_id: int
    z_cycles: float
    sigma_cycles: float


class StreamingCarrier:
    """Tones tracked from the sample they join at; `push` samples, `take` differences."""

    def __init__(self, sample_rate_hz: float, cfg: CarrierConfig | None = None, lag_s: float = LAG_S,
                 keep_s: float = KEEP_S) -> None:
        self.cfg = cfg or CarrierConfig()
        validate_rate(sample_rate_hz, self.cfg.loop.acq_range_hz, self.cfg.sub_rate_hz)
        self.fs = float(sample_rate_hz)
        self.lag_s, self.keep_s = lag_s, keep_s
        self.n_samples = 0                      # samples pushed so far (capture index of the next)
        self.tones: dict[int, _Tone] = {}
        self.norad: dict[int, int] = {}
        self._next_epoch: dict[int, int] = {}   # first epoch index not yet given, per tone
        self._given: set[int] = set()           # tones whose epochs have been given once
        self._stopped: list[StreamedDifference] = []   # final differences of tones stopped since `take`
        self.counts = {"tones": 0, "epochs": 0, "differences": 0, "breaks": {r: 0 for r in BREAK_REASONS}}

    @property
    def t_data(self) -> float:
        return self.n_samples / self.fs

    def start_tone(self, key: int, norad_id: int, aiding: Aiding) -> None:
        """Track tone `key` (satellite norad_id) from the next whole decimated sample on."""
        if key in self.tones:
            return
        m, _ = block_factors(self.fs, self.cfg.sub_rate_hz)
        k0 = -(-self.n_samples // m)     # ceil: the first whole block not yet pushed
        self.tones[key] = _Tone(aiding, self.fs, self.cfg, k0)
        self.norad[key] = int(norad_id)
        first = k0 * m / self.fs
        self._next_epoch[key] = int(math.floor(first / self.cfg.epoch_s)) + 1

    def stop_tone(self, key: int) -> None:
        """No longer track tone `key` (its satellite has gone, or is about to leave the band): its
        epochs that are final now (`lag_s` behind the data) are kept for the next `take`, the
        later ones, which no later prompt can confirm, are not given."""
        if key in self.tones:
            self._stopped += self._take_tone(key, self.tones[key], final=False, batch=False)
        for d in (self.tones, self.norad, self._next_epoch):
            d.pop(key, None)
        self._given.discard(key)    # started again later, it is a new tone with a first window

    def set_aiding(self, key: int, aiding: Aiding) -> None:
        """A longer aiding curve for a tracked tone (the predictions reach further)."""
        if key in self.tones:
            self.tones[key].front.aiding = aiding

    def push(self, x: np.ndarray) -> None:
        """The capture's next samples (complex64)."""
        for tone in self.tones.values():
            skip = tone.front.next_sample - self.n_samples
            if skip < x.size:
                tone.feed(x[max(0, skip):])
        self.n_samples += x.size

    def take(self, final: bool = False) -> list[StreamedDifference]:
        """The phase differences made final since the last call (module doc); final: the capture
        has ended, every epoch its samples give is final."""
        out, self._stopped = self._stopped, []
        for key, tone in self.tones.items():
            out += self._take_tone(key, tone, final, batch=not final)
        self.counts["differences"] += len(out)
        return out

    def _take_tone(self, key: int, tone: _Tone, final: bool, batch: bool) -> list[StreamedDifference]:
        """One tone's new differences up to `lag_s` behind the data (none behind: final); batch:
        only once `EVERY_S` of epochs are ready."""
        lag = 0.0 if final else self.lag_s
        e_ready = int(math.floor((self.t_data - lag) / self.cfg.epoch_s + 1e-9))
        e_first = self._next_epoch[key]
        if e_ready < e_first or (batch and (e_ready - e_first + 1) * self.cfg.epoch_s < EVERY_S - 1e-9):
            return []
        tr = _epochs(tone, self.cfg, max(1, e_first - 1), e_ready)
        if not tr.t_s.size:
            return []
        n = tr.t_s.size
        d = phase_differences(tr.t_s, np.full(n, self.norad[key]), np.full(n, key), tr.phase_cycles,
                              tr.sigma_cycles, tr.locked, tr.arc, self.cfg.epoch_s)
        # every pair of the window ends at a new epoch (the repeated one starts the window)
        out = [StreamedDifference(float(t), float(i), key, self.norad[key], float(z), float(s))
               for t, i, z, s in zip(d.t, d.interval_s, d.z_cycles, d.sigma_cycles)]
        # the window's first epoch was counted by the window before it; a tone is counted with its
        # first window (one stopped before it gave none: pairs = epochs - tones holds)
        self.counts["epochs"] += n - (1 if key in self._given else 0)
        if key not in self._given:
            self.counts["tones"] += 1
            self._given.add(key)
        for r in BREAK_REASONS:
            self.counts["breaks"][r] += d.counts["breaks"][r]
        self._next_epoch[key] = int(round(tr.t_s[-1] / self.cfg.epoch_s)) + 1   # the prompts may end sooner
        tone.trim(int((e_ready * self.cfg.epoch_s - self.keep_s) * tone.front.sub_rate_hz))
        return out
