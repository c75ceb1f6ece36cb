"""Scoring a carrier track against the synthetic bench's truth phase (tests, benchmark).

- phase error per locked epoch: tracked minus true phase (cycles), minus the arc's median
  (each arc has its own ambiguity; the tracker's fractional phase is real, its integer is not);
- an *undetected jump*: an arc inside which the error moves by more than half a cycle
  (a slip the tracker did not flag);
- an injected slip event is *detected* when the arc of the last locked epoch before it
  differs from the arc of the first locked epoch after it (or there is none: no phase was
  given across it); a *false alarm* is a slip flag farther than `event_margin_s` from
  every event;
- relock delay: from the event's end to the next locked epoch.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from leonav_runtime.beacons.carrier import CarrierConfig, CarrierTrack, track_tones
from leonav_runtime.beacons.carrier_front import Aiding
from leonav_runtime.beacons.synthetic_phase import PhaseCapture

AID_STEP_S = 0.05


@dataclasses.dataclass
class TrackScore:
    epochs: int
    locked_fraction: float          # from the first locked epoch on
    first_lock_s: float
    jitter_cycles: float            # rms of the error about each arc's median (locked epochs)
    undetected_jumps: int
    events: int
    events_detected: int
    false_alarms: int
    relock_delay_s: list


def score(track: CarrierTrack, cap: PhaseCapture, tone: int, event_margin_s: float = 1.5) -> TrackScore:
    """Score one tone's track (see module doc)."""
    t = track.t_s
    err = track.phase_cycles - np.interp(t, cap.t_s, cap.phase_cycles[tone])
    resid, jumps = [], 0
    for a in np.unique(track.arc[track.arc >= 0]):
        e = err[track.arc == a]
        e = e - np.median(e)
        jumps += int(np.max(np.abs(e)) > 0.5)
        resid.append(e)
    r = np.concatenate(resid) if resid else np.zeros(0)
    events = list(cap.tones[tone].slips)
    detected, near, delays = 0, np.zeros(t.size, bool), []
    for ev in events:
        end = ev.t_s + ev.duration_s
        before = track.arc[(t < ev.t_s) & (track.arc >= 0)]
        after = track.arc[(t > end) & (track.arc >= 0)]
        detected += int(before.size == 0 or after.size == 0 or before[-1] != after[0])
        near |= (t >= ev.t_s) & (t <= end + event_margin_s)
        nxt = t[(t > end) & track.locked]
        delays.append(float(nxt[0] - end) if nxt.size else float("inf"))
    first = float(t[np.argmax(track.locked)]) if track.locked.any() else float("inf")
    return TrackScore(int(t.size), track.locked_fraction(), first,
                      float(np.sqrt(np.mean(r**2))) if r.size else float("nan"), jumps, len(events), detected,
                      int(np.sum(track.slip & ~near)), delays)


def track_capture(cap: PhaseCapture, ephemeris_dt_s: float = 0.05, lo_error_hz: float = 5.0,
                  cfg: CarrierConfig | None = None, block_samples: int = 1 << 20) -> list[CarrierTrack]:
    """Track every tone of a bench capture with the aiding a pipeline would give it: the pass
    seen `ephemeris_dt_s` late (0.05 s: ~380 m along track; 200 Hz of Doppler error at
    closest approach) and the common LO estimate `lo_error_hz` off."""
    t = np.arange(-2 * AID_STEP_S, cap.cfg.duration_s + 3 * AID_STEP_S, AID_STEP_S)
    aid = [Aiding(t, cap.predicted_baseband(t, i, ephemeris_dt_s, lo_error_hz)[0], f"tone {i}")
           for i in range(len(cap.tones))]
    blocks = (cap.iq[k:k + block_samples] for k in range(0, cap.iq.size, block_samples))
    return track_tones(blocks, cap.sample_rate_hz, aid, cap.cfg.duration_s, cfg)
