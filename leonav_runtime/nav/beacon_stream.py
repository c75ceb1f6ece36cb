"""The beacon pipeline on a capture that is still being written: chunks in, Doppler-rate out.

The streaming twin of `beacons.pipeline.process_capture`, built from the beacons package's
public pieces (it does not change them):
- IQ blocks -> `waterfall.iter_spectra` -> `ridges.RidgeTracker.add_block`, as in the batch
  pipeline, block by block (`block_s` of samples);
- every ridge still being tracked is measured as soon as a measurement epoch's fit window is
  complete (`doppler.ridge_measurements` on the ridge's recent points: epochs k * 1 s, fit
  over +-1 s), so an epoch is ready one half-window after its time;
- association with a joint LO offset and drift (`associate.associate_capture`) is re-run on
  the measurements of the last `window_s` whenever new epochs are ready, against predictions
  (`predict.predict_visible`, SGP4 through the generated model) refreshed every
  `predict_every_s` over a horizon around now; the evidence grows with every epoch;
- each new epoch of an associated comb is emitted once (its combined, drift-corrected rate,
  `CaptureAssociation.filter_measurements`), never revised afterwards.
Memory stays bounded: finished tracks are dropped from the tracker once measured, tracks keep
their last `track_keep_s` of points, measurements their last `window_s`. Differences from the
batch pipeline (named for the README): no fragment joining and no tone-shape filter at the end
of the capture (noise tracks simply find no satellite); the LO drift is estimated from the
window, not the whole capture; a ridge shorter than one fit window gives no measurement; an
association made early is not revised for epochs already sent.
"""
from __future__ import annotations

import dataclasses
import datetime as _dt
import time

import numpy as np

from leonav_runtime.beacons.associate import associate_capture
from leonav_runtime.beacons.carrier_front import MAX_TONE_FRACTION, Aiding
from leonav_runtime.beacons.carrier_hook import AID_STEP_S
from leonav_runtime.beacons.carrier_stream import StreamingCarrier
from leonav_runtime.beacons.doppler import RidgeMeasurements, ridge_measurements
from leonav_runtime.beacons.pipeline import PipelineConfig
from leonav_runtime.beacons.predict import predict_visible
from leonav_runtime.beacons.ridges import Ridge, RidgeTracker
from leonav_runtime.beacons.waterfall import StftConfig, band_bins
from leonav_runtime.nav.push_stft import PushStft

TONE_GONE_S = 5.0   # a tracked tone whose STFT ridge has been gone this long is no longer tracked
# a tone starts when its aiding stays inside the front end's band (0.45 fs) this long ahead, and
# stops when it would leave the band within BAND_MARGIN_S (the samples already pushed and a block)
TONE_BAND_AHEAD_S, BAND_MARGIN_S = 5.0, 2.0
MEAS_FIELDS = ("t_s", "doppler_hz", "sigma_doppler_hz", "rate_hz_s", "sigma_rate_hz_s", "n_points", "snr_db")


@dataclasses.dataclass
class StreamSettings:
    window_s: float = 60.0          # measurements kept for the association
    predict_every_s: float = 30.0
    predict_ahead_s: float = 45.0
    track_keep_s: float = 12.0      # points kept per track (the tracker uses its last second)
    max_lag_s: float = 2.0          # an epoch not ready this long after its newest sample is not sent


@dataclasses.dataclass
class Emitted:
    """One Doppler-rate measurement: capture time t_s, satellite, rate and 1-sigma (Hz/s), and how
    late it came: `data_lag_s` from its newest sample to the end of the data processed when it
    was emitted (capture time), `wall_s` the host clock when it was emitted (live: compare with
    the sample's arrival; `max_lag_s` applies to the later of the two lags)."""

    t_s: float
    norad_id: int
    sat_index: int
    rate_hz_s: float
    sigma_hz_s: float
    data_lag_s: float
    wall_s: float


def _concat(a: RidgeMeasurements, b: RidgeMeasurements) -> RidgeMeasurements:
    return RidgeMeasurements(a.ridge_id, *(np.concatenate([getattr(a, f), getattr(b, f)]) for f in MEAS_FIELDS))


def _since(m: RidgeMeasurements, t0: float) -> RidgeMeasurements:
    k = np.searchsorted(m.t_s, t0)
    return RidgeMeasurements(m.ridge_id, *(getattr(m, f)[k:] for f in MEAS_FIELDS))


class BeaconStream:
    """Feed IQ (`push`, complex64) or spectrum blocks (`add_block`); take measurements with `take()`."""

    def __init__(self, sample_rate_hz: float, rf_center_hz: float, f_c_hz: float, elements,
                 cfg: PipelineConfig | None = None, settings: StreamSettings | None = None,
                 carrier_phase: bool = False) -> None:
        """carrier_phase: also track the carrier of every identified tone (`take_phase`)."""
        self.cfg = cfg = cfg or PipelineConfig(f_c_hz=f_c_hz, band_hz=min(1.2e6, sample_rate_hz))
        self.settings = settings or StreamSettings()
        self.fs = sample_rate_hz
        self.rf_center_hz = rf_center_hz
        self.elements = elements
        self.stft = StftConfig.for_rate(sample_rate_hz, cfg.band_hz, cfg.fft_size, cfg.overlap, cfg.dc_notch_hz)
        _, f_hz = band_bins(self.stft, sample_rate_hz)
        self.tracker = RidgeTracker(f_hz, cfg.tracker)
        self.stft_push = PushStft(self.stft, sample_rate_hz)
        self.site = None
        self.start_utc: _dt.datetime | None = None
        self.t_mono_start: float | None = None   # host clock of the first sample (live: wall lag)
        self._ids: dict[int, tuple[object, int]] = {}   # id(track) -> (track, ridge id)
        self._next_epoch: dict[int, float] = {}
        self._meas: dict[int, RidgeMeasurements] = {}
        self._emitted_t: dict[int, float] = {}  # norad -> last emitted epoch
        self._pred = None
        self._pred_span = (np.inf, -np.inf)
        self._out: list[Emitted] = []
        self.t_data = 0.0                        # capture time processed so far (s)
        self.counts = {"blocks": 0, "ridges": 0, "epochs": 0, "associations": 0, "emitted": 0,
                       "predictions": 0, "tracks_dropped": 0, "too_late": 0}
        if carrier_phase:
            self.counts.update(tones_tracked=0, tones_left_out=0, tones_stopped=0, tones_left_band=0)
        self.max_lag_seen_s = 0.0
        self.last_summary: dict = {}
        self.carrier = StreamingCarrier(sample_rate_hz) if carrier_phase else None
        self._phase_final = False          # flushed: the last epochs need no lag
        self.tones: dict[int, tuple[int, int, float]] = {}   # ridge id -> (norad, element row, tone offset Hz)
        self._aid_offset: dict[int, float] = {}              # ridge id -> aiding's constant (Hz)
        self._gone_since: dict[int, float] = {}              # tracked tone -> when its ridge ended (s)
        self._ended: set[int] = set()                        # ridges stopped or left out: not started again
        # stopped tones whose last epochs the last take_phase gave, those stopped since; ridges out of band
        self._retired, self._stopping, self._left_out = {}, {}, set()

    def set_site(self, site, start_utc: _dt.datetime) -> None:
        """The receiver's site and the capture's first-sample UTC (needed to associate)."""
        self.site, self.start_utc = site, start_utc

    # -- per block
    def push(self, samples: np.ndarray) -> None:
        for blk in self.stft_push.push(samples):
            self.add_block(blk)
        if self.carrier is not None:    # after the blocks: a tone identified in them starts here
            self.carrier.push(samples)

    def flush(self) -> None:
        for blk in self.stft_push.flush():
            self.add_block(blk)
        self._phase_final = True

    @property
    def phase_tones(self) -> dict:
        """Ridge id -> (NORAD id, element row, offset Hz) of every tone tracked or stopped."""
        return {**self._retired, **self._stopping, **self.tones}

    def take_phase(self) -> list:
        """Carrier-phase differences made final since the last call (`carrier_stream.StreamedDifference`,
        capture time); their tones' satellite rows and offsets are in `phase_tones` until the next call."""
        if self.carrier is None:
            return []
        self._retired, self._stopping = self._stopping, {}
        return self.carrier.take(final=self._phase_final)

    def add_block(self, blk) -> None:
        self.tracker.add_block(blk)
        self.counts["blocks"] += 1
        self.t_data = float(blk.t_s[-1])
        new = self._measure()
        if new and self.site is not None:
            self._associate()
        self._trim()
        if self.carrier is not None:
            self._stop_gone_tones()

    def _stop_gone_tones(self) -> None:
        """Stop tracking a tone whose ridge the STFT tracker has let go of for `TONE_GONE_S` (the
        satellite set or faded; a live run meets a new satellite every few minutes), whose
        aiding ends within a second (its satellite left the predictions), or whose Doppler takes
        it out of the front end's band within `BAND_MARGIN_S` (counted as tones_left_band too)."""
        alive = {entry[1] for entry in self._ids.values()}
        for key in list(self.carrier.tones):
            aiding = self.carrier.tones[key].front.aiding
            if aiding.t_s[-1] < self.t_data + 1.0:
                self._stop(key)
            elif not self._in_band(aiding, BAND_MARGIN_S):
                self._stop(key)
                self.counts["tones_left_band"] += 1
            elif key in alive:
                self._gone_since.pop(key, None)
            elif self.t_data - self._gone_since.setdefault(key, self.t_data) >= TONE_GONE_S:
                self._stop(key)

    def _stop(self, key: int) -> None:
        """A tracked tone ends for good (its ridge is not started again); its final epochs still come
        with the next `take_phase`, so its satellite and offset stay known (`phase_tones`)."""
        self.carrier.stop_tone(key)
        if key in self.tones:
            self._stopping[key] = self.tones[key]
        for d in (self.tones, self._aid_offset, self._gone_since):
            d.pop(key, None)
        self._ended.add(key)
        self.counts["tones_stopped"] += 1

    def _in_band(self, aiding: Aiding, ahead_s: float) -> bool:
        """Whether the aided frequency stays within 0.45 fs of the centre from now to `ahead_s` on."""
        t = np.linspace(self.t_data, self.t_data + ahead_s, 21)
        return bool(np.all(np.abs(aiding.at(t)) <= MAX_TONE_FRACTION * self.fs))

    def _rid(self, tr) -> int:
        entry = self._ids.get(id(tr))
        if entry is None or entry[0] is not tr:
            entry = self._ids[id(tr)] = (tr, self.counts["ridges"])
            self.counts["ridges"] += 1
        return entry[1]

    def _measure(self) -> int:
        hw, step = self.cfg.fit_half_window_s, self.cfg.meas_interval_s
        new = 0
        for tr in self.tracker.active + self.tracker.done:
            if len(tr.t) < 8:
                continue
            rid = self._rid(tr)
            nxt = self._next_epoch.get(rid)
            if nxt is None:
                nxt = float(np.ceil((tr.t[0] + hw) / step) * step)
            if tr.t[-1] - hw < nxt:       # no complete fit window yet
                continue
            t = np.asarray(tr.t)
            k = int(np.searchsorted(t, nxt - hw - 0.5))      # a margin: the epoch's window must be inside
            ridge = Ridge(t[k:], np.asarray(tr.f[k:]), np.asarray(tr.snr[k:]), rid)
            m = ridge_measurements(ridge, self.rf_center_hz, self.cfg.f_c_hz, step, hw)
            m = _since(m, nxt - 1e-9)
            on_grid = np.abs(m.t_s / step - np.round(m.t_s / step)) < 1e-6   # not the short-ridge fallback
            if not on_grid.all():
                m = RidgeMeasurements(m.ridge_id, *(getattr(m, f)[on_grid] for f in MEAS_FIELDS))
            self._next_epoch[rid] = float(np.floor((t[-1] - hw) / step) * step) + step
            if m.t_s.size:
                self._meas[rid] = _concat(self._meas[rid], m) if rid in self._meas else m
                new += m.t_s.size
        self.counts["epochs"] += new
        return new

    def _predictions(self):
        s = self.settings
        lo, hi = self._pred_span
        t_now = self.t_data
        if self._pred is None or t_now + 5.0 > hi or t_now - s.window_s < lo and lo > 0:
            t0 = max(0.0, t_now - s.window_s - 2.0)
            t1 = t_now + s.predict_ahead_s
            start = self.start_utc + _dt.timedelta(seconds=t0)
            pred = predict_visible(self.elements, self.site, start, t1 - t0, mask_deg=self.cfg.mask_deg,
                                   f_c_hz=self.cfg.f_c_hz)
            self._pred = dataclasses.replace(pred, t_s=pred.t_s + t0, start_utc=self.start_utc)
            self._pred_span = (t0, t1)
            self.counts["predictions"] += 1
        return self._pred

    def _associate(self) -> None:
        pred = self._predictions()
        if not len(pred.names):
            return
        meas = [m for m in self._meas.values() if m.t_s.size]
        if not meas:
            return
        ca = associate_capture(meas, pred, self.cfg.association)
        self.counts["associations"] += 1
        self.last_summary = {"lo_offset_hz": ca.lo.offset_hz, "lo_drift_hz_s": ca.lo.drift_hz_s,
                             "drift_removed": ca.lo.drift_removed,
                             "status": {s: sum(a.status == s for a in ca.associations)
                                        for s in ("associated", "ambiguous", "unassociated")}}
        hw = self.cfg.fit_half_window_s
        now = time.monotonic()
        for a in ca.associations:
            if a.status != "associated" or not a.carrier or a.ridge_id not in ca.filter_measurements:
                continue
            m = ca.filter_measurements[a.ridge_id]
            last = self._emitted_t.get(a.norad_id, -np.inf)
            for k in np.flatnonzero(m.t_s > last + 1e-6):
                newest = float(m.t_s[k]) + hw
                lag = self.t_data - newest
                if self.t_mono_start is not None:
                    lag = max(lag, now - (self.t_mono_start + newest))
                if lag > self.settings.max_lag_s:
                    self.counts["too_late"] += 1
                    continue
                self.max_lag_seen_s = max(self.max_lag_seen_s, lag)
                self._out.append(Emitted(float(m.t_s[k]), a.norad_id, int(pred.sat_index[a.sat_row]),
                                         float(m.rate_hz_s[k]), float(m.sigma_rate_hz_s[k]), lag, now))
            if m.t_s.size:
                self._emitted_t[a.norad_id] = max(last, float(m.t_s[-1]))
        if self.carrier is not None:
            self._track_tones(ca, pred)

    def _track_tones(self, ca, pred) -> None:
        """Start the carrier of every identified tone with a comb index (its offset from the centre
        is then known), and give every tracked tone the aiding of the current predictions: the
        predicted Doppler plus the median of its ridge's baseband frequency minus it."""
        tracks = {entry[1]: entry[0] for entry in self._ids.values()}
        spacing = self.cfg.association.comb.spacing_hz
        t = np.arange(max(0.0, self._pred_span[0]), self._pred_span[1], AID_STEP_S)
        if t.size < 4:
            return
        curves = pred.at(t)[0]
        updated = set()
        for a in ca.associations:
            if a.status != "associated" or a.sat_row < 0 or a.tone_index is None or a.ridge_id in self._ended:
                continue
            tr = tracks.get(a.ridge_id)
            offset = self._aid_offset.get(a.ridge_id)
            if offset is None:
                if tr is None or len(tr.t) < 8:
                    continue
                on_ridge = pred.at(np.asarray(tr.t))[0][a.sat_row]
                # fixed once the tone is tracked: a new median each second (the LO drifts under it)
                # would step the aiding's frequency, and each step is a transient in the loop
                offset = float(np.median(np.asarray(tr.f) - on_ridge))
            aid = Aiding(t, curves[a.sat_row] + offset, f"ridge {a.ridge_id} ({a.name})")
            updated.add(a.ridge_id)
            if a.ridge_id in self.tones:
                self.carrier.set_aiding(a.ridge_id, aid)
            elif not self._in_band(aid, TONE_BAND_AHEAD_S):     # soon beyond the front end's band: counted
                if a.ridge_id not in self._left_out:           # once, and looked at again next time (a
                    self._left_out.add(a.ridge_id)             # tone entering the band is seen at its edge)
                    self.counts["tones_left_out"] += 1
            else:
                tone = (a.norad_id, int(pred.sat_index[a.sat_row]), a.tone_index * spacing)
                for old in [k for k, v in self.tones.items() if v == tone]:
                    self._stop(old)                  # a new ridge of the same tone: one phase per tone
                self.tones[a.ridge_id] = tone
                self._aid_offset[a.ridge_id] = offset
                self.carrier.start_tone(a.ridge_id, a.norad_id, aid)
                self.counts["tones_tracked"] += 1
        # a tracked tone whose ridge is not associated this time keeps its aiding up to date by its
        # satellite (element row); one whose satellite left the predictions stops when its aiding ends
        for key, (_, row, _) in self.tones.items():
            rows = np.flatnonzero(pred.sat_index == row)
            if key not in updated and rows.size:
                self.carrier.set_aiding(key, Aiding(t, curves[rows[0]] + self._aid_offset[key], f"ridge {key}"))

    def _trim(self) -> None:
        s = self.settings
        keep_from = self.t_data - s.window_s
        for rid in list(self._meas):
            m = _since(self._meas[rid], keep_from)
            if m.t_s.size:
                self._meas[rid] = m
            else:
                del self._meas[rid]
        # finished tracks: measured already; drop them (the tracker would keep them for finish())
        hw = self.cfg.fit_half_window_s
        for tr in list(self.tracker.done):
            entry = self._ids.get(id(tr))
            nxt = self._next_epoch.get(entry[1], np.inf) if entry is not None and entry[0] is tr else np.inf
            if len(tr.t) < 8 or tr.t[-1] - hw < nxt:
                self.tracker.done.remove(tr)
                self.counts["tracks_dropped"] += 1
        live = {id(tr) for tr in self.tracker.active + self.tracker.done}
        for key in [k for k in self._ids if k not in live]:     # tracks the tracker let go
            self._next_epoch.pop(self._ids.pop(key)[1], None)
        cut = self.t_data - s.track_keep_s
        for tr in self.tracker.active:     # old points of long tracks (the tracker uses the last 256)
            if len(tr.t) > 2000 and tr.t[0] < cut:
                k = int(np.searchsorted(np.asarray(tr.t), cut))
                k = min(k, len(tr.t) - 1000)
                if k > 0:
                    del tr.t[:k], tr.f[:k], tr.snr[:k]

    def take(self) -> list[Emitted]:
        out, self._out = self._out, []
        self.counts["emitted"] += len(out)
        return out
