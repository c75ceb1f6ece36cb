"""The capture -> `beacon_stream.BeaconStream` -> Doppler-rate tables on the navigator's road.

- Live (and paced playback), `BeaconProcess`: the recorder's SDR thread writes `session/sdr.cu8`
  (flushed per block); a separate process reads the file as it grows, in `CHUNK_S` pieces, runs
  the stream and sends finished Doppler-rate rows (with SGP4 satellite states) back. The
  navigator's thread never waits for the SDR or the STFT (no shared interpreter lock: on a
  Pi 4 the beacon work gets its own core), and the capture is recorded whatever happens.
- Fast playback, `BeaconFeed.advance_to(t_mono)`: the recorded samples up to that host time are
  pushed in the caller's thread, in step with the serial chunks (deterministic).
Measurements are placed on the road's axis with the capture's first-sample host stamp
(SigMF `leonav:t_mono_start_s`) through the GNSS time map, as the replay does, and get their
satellite states from `replay.beacon_table.doppler_rate_table` (SGP4, sigma floor).
"""
from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np

from leonav_runtime.beacons.predict import Site
from leonav_runtime.nav.beacon_stream import BeaconStream
from leonav_runtime.replay.beacon_table import BeaconMeasurements, default_elements, doppler_rate_table
from leonav_runtime.replay.timebase import utc_of

CHUNK_S = 0.1


def capture_meta(meta_path: Path) -> dict:
    """Sample rate, RF centre, host stamp of the first sample from a recorder's sdr.sigmf-meta."""
    doc = json.loads(Path(meta_path).read_text())
    g = doc.get("global", {})
    cap = (doc.get("captures") or [{}])[0]
    return {"sample_rate_hz": float(g["core:sample_rate"]),
            "rf_center_hz": float(g.get("leonav:rf_center_hz", cap.get("core:frequency", 0.0) +
                                        g.get("leonav:lnb_lo_hz", 0.0))),
            "lnb_lo_hz": float(g.get("leonav:lnb_lo_hz", 0.0)), "gain_db": g.get("leonav:gain_db", "auto"),
            "t_mono_start_s": g.get("leonav:t_mono_start_s")}


def carrier(rf_center_hz: float) -> tuple[float, str]:
    """Beacon carrier f_c: the capture's RF centre inside the Ku downlink band, else the default
    (the rule of `replay.beacon_table.capture_carrier`)."""
    from leonav_runtime.gen.constants import STARLINK_BEACON_HZ
    from leonav_runtime.replay.beacon_table import KU_DOWNLINK_HZ

    if math.isfinite(rf_center_hz) and KU_DOWNLINK_HZ[0] <= rf_center_hz <= KU_DOWNLINK_HZ[1]:
        return rf_center_hz, "capture RF centre (tuned frequency + LNB LO)"
    return STARLINK_BEACON_HZ, f"default {STARLINK_BEACON_HZ / 1e9:g} GHz (capture RF centre {rf_center_hz / 1e9:.6g} GHz)"


def cu8_to_complex(raw: bytes) -> np.ndarray:
    """Interleaved cu8 -> complex64 with the scaling of `beacons.capture_io` (full scale ~ +-1)."""
    f = np.frombuffer(raw, np.uint8)[: len(raw) // 2 * 2].astype(np.float32)
    f -= 127.5
    f *= 1.0 / 127.5
    return f.view(np.complex64)


def emitted_names(emitted: list, elements) -> dict[int, str]:
    """{NORAD id: object name} of the satellites of emitted measurements (the element sets' names)."""
    return {int(e.norad_id): str(elements.names[int(e.sat_index)]).strip() for e in emitted}


def emitted_table(emitted: list, start_unix: float, epoch_unix: float, elements, sigma_floor_hz_s: float,
                  operator=None, stats: dict | None = None):
    """`inputs.DopplerRateTable` of emitted measurements on the road's axis (t s since `epoch_unix`);
    operator: an `orbits.operator_folder.OperatorFolder` whose files give the states of the
    satellites they cover (read as the satellites are first measured; counted in `stats`)."""
    t = np.array([start_unix + e.t_s - epoch_unix for e in emitted])
    meas = BeaconMeasurements(t, np.array([e.norad_id for e in emitted], int),
                              np.array([e.sat_index for e in emitted], int),
                              np.array([e.rate_hz_s for e in emitted]), np.array([e.sigma_hz_s for e in emitted]))
    files = None if operator is None else operator.files(emitted_names(emitted, elements))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return doppler_rate_table(meas, elements, utc_of(epoch_unix), sigma_floor_hz_s, files, stats=stats)


def phase_names(diffs: list, tones: dict, elements) -> dict[int, str]:
    """{NORAD id: object name} of streamed phase differences' satellites."""
    return {int(d.norad_id): str(elements.names[tones[d.key][1]]).strip() for d in diffs}


def emitted_phase_table(diffs: list, tones: dict, start_unix: float, epoch_unix: float, elements, origin,
                        operator=None, stats: dict | None = None):
    """`inputs.CarrierPhaseTable` of streamed phase differences (`beacon_stream.BeaconStream.take_phase`)
    on the road's axis: each tone referred to the channel centre and its satellite's states at both
    ends of the interval, as the replay makes them (`replay.beacon_table.carrier_phase_table`);
    tones: ridge id -> (NORAD id, element row, tone offset Hz); origin: the road's (lat, lon rad, h m)."""
    from leonav_runtime.inputs import PhaseDifferences
    from leonav_runtime.orbits.geometry import geodetic_to_ecef
    from leonav_runtime.replay.beacon_table import PhaseMeasurements, carrier_phase_table

    t = np.array([start_unix + d.t_s - epoch_unix for d in diffs])
    pd = PhaseDifferences(t, np.array([d.interval_s for d in diffs]), np.array([d.norad_id for d in diffs], int),
                          np.array([d.key for d in diffs], int), np.array([d.z_cycles for d in diffs]),
                          np.array([d.sigma_cycles for d in diffs]), {})
    rows = np.array([tones[d.key][1] for d in diffs], int)
    pm = PhaseMeasurements(pd, rows, np.array([tones[d.key][2] for d in diffs], float), {})
    files = None if operator is None else operator.files(phase_names(diffs, tones, elements))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return carrier_phase_table(pm, elements, utc_of(epoch_unix), geodetic_to_ecef(*origin), files, stats=stats)


def stream_tables(stream, ready: bool, start_unix: float, epoch_unix: float, elements, sigma_floor_hz_s: float,
                  operator, origin, counts: dict):
    """What the beacon stream has made since the last call: (emitted Doppler-rate measurements,
    their `DopplerRateTable` or None, phase differences, their `CarrierPhaseTable` or None), the
    tables on the road's axis (`epoch_unix`) at its site `origin`. Before the road is `ready`
    (its axis and site known) the stream's output makes no table. Counts tables, measurements,
    phase_tables and phase_differences in `counts`."""
    emitted, diffs = stream.take(), stream.take_phase()
    rate = phase = None
    if ready and emitted:
        rate = emitted_table(emitted, start_unix, epoch_unix, elements, sigma_floor_hz_s, operator, counts)
        counts["tables"] += 1
        counts["measurements"] += int(rate.t.size)
    if ready and diffs:
        phase = emitted_phase_table(diffs, stream.phase_tones, start_unix, epoch_unix, elements, origin, operator,
                                    counts)
        counts["phase_tables"] = counts.get("phase_tables", 0) + 1
        counts["phase_differences"] = counts.get("phase_differences", 0) + int(phase.t.size)
    return emitted, rate, diffs, phase


class CaptureFile:
    """A cu8 file read from the start in pieces, also while it is still being written."""

    def __init__(self, path: Path) -> None:
        self._fh = open(path, "rb")
        self._pending = b""
        self.n_read = 0

    def read(self, max_samples: int) -> np.ndarray | None:
        """Up to `max_samples` new samples (complex64), None when nothing new is there yet."""
        data = self._pending + self._fh.read(max(0, 2 * max_samples - len(self._pending)))
        n = len(data) // 2 * 2
        self._pending = data[n:]
        if not n:
            return None
        self.n_read += n // 2
        return cu8_to_complex(data[:n])

    def close(self) -> None:
        self._fh.close()


class BeaconFeed:
    """Fast playback: the session's capture through a `BeaconStream` in step with the serial chunks."""

    def __init__(self, data_path: Path, meta: dict, f_c_hz: float, elements, sigma_floor_hz_s: float,
                 operator=None, carrier_phase: bool = False) -> None:
        """operator: an `orbits.operator_folder.OperatorFolder` (--operator-ephemerides), shared with
        the navigator's road (whose consider term reads the same files' covariance)."""
        self.data_path = Path(data_path)
        self.meta = meta
        self.elements = elements
        self.sigma_floor = sigma_floor_hz_s
        self.operator = operator
        self.stream = BeaconStream(meta["sample_rate_hz"], meta["rf_center_hz"], f_c_hz, elements,
                                   carrier_phase=carrier_phase)
        self.capture = CaptureFile(self.data_path)
        self.notes: list[str] = []
        self.start_unix = math.nan
        self.counts = {"samples": 0, "tables": 0, "measurements": 0}
        self.error = ""

    def set_site(self, navigator) -> None:
        """Once the road has started: the site (its origin) and the capture start through the time map."""
        road = navigator.road
        if math.isfinite(self.start_unix) or not road.started or self.meta.get("t_mono_start_s") is None:
            return
        self.start_unix = road.tmap.to_utc(float(self.meta["t_mono_start_s"]))
        start = utc_of(self.start_unix)
        if self.elements is None:
            self.elements = self.stream.elements = default_elements(start, self.notes)
        self.stream.set_site(Site(*road.origin), start)

    def advance_to(self, t_mono: float, navigator) -> None:
        """Push the samples recorded up to host time `t_mono`; hand what is finished to the navigator."""
        if self.meta.get("t_mono_start_s") is None:
            return
        self.set_site(navigator)
        target = int((t_mono - float(self.meta["t_mono_start_s"])) * self.meta["sample_rate_hz"])
        chunk = int(CHUNK_S * self.meta["sample_rate_hz"])
        while self.capture.n_read < target:
            z = self.capture.read(min(chunk, target - self.capture.n_read))
            if z is None:
                break
            self.stream.push(z)
        self.counts["samples"] = self.capture.n_read
        self._hand_over(navigator)

    def finish(self, navigator) -> None:
        """The playback ended: the stream's last partial STFT block and its last phase epochs (no
        lag left to wait for) are made, and handed to the navigator before it settles; the samples
        after the last serial chunk are not read (the filter has no IMU there)."""
        if self.meta.get("t_mono_start_s") is None:
            return
        self.set_site(navigator)
        self.stream.flush()
        self.counts["flushed_at_samples"] = self.capture.n_read
        self._hand_over(navigator)

    def _hand_over(self, navigator) -> None:
        road = navigator.road
        ready = road.started and math.isfinite(self.start_unix)
        _, rate, _, phase = stream_tables(self.stream, ready, self.start_unix, road.epoch_unix if ready else math.nan,
                                          self.elements, self.sigma_floor, self.operator, road.origin, self.counts)
        if rate is not None:
            navigator.on_doppler_rate(rate)
        if phase is not None:
            navigator.on_carrier_phase(phase)

    def poll(self, navigator) -> None:
        """Nothing arrives on its own in fast playback (`advance_to` delivers)."""

    def stop(self) -> None:
        self.capture.close()

    def summary(self) -> dict:
        return stream_summary(self.stream, self.counts, self.error, self.notes, self.start_unix)


def stream_summary(stream: BeaconStream | None, counts: dict, error: str, notes: list, start_unix: float) -> dict:
    return {"counts": dict(counts), "stream": None if stream is None else dict(stream.counts),
            "max_lag_s": None if stream is None else stream.max_lag_seen_s,
            "last_association": None if stream is None else stream.last_summary, "error": error, "notes": notes,
            "capture_start_utc": utc_of(start_unix) if math.isfinite(start_unix) else None}
