"""One time axis for a recorded session, and the IMU table on it.

- `mono_to_utc_function`: host monotonic stamps -> UTC through the session's GNSS time map
  (RMC/ZDA/NAV-PVT tags), corrected for the tag message's own UART serialization and the
  receiver's output latency; without tags, the host wall clock of session.json (noted).
- `regular_sample_times`: the WitMotion samples are regular in the sensor's clock, so their
  times are a straight-line fit of the arrival stamps against the sample index (gaps of
  missing cycles detected from the stamp spacing and counted); the host's read jitter does
  not enter the intervals.
- `imu_table`: WitMotion samples -> `inputs.ImuTable` on that axis (t = 0 is the first IMU
  sample; a sample's rate and specific force are the means over the interval ending at it,
  body FLU, no axis change, hardware/README.md), and `filter_profile`: the WT901 profile
  plus the protocol's quantization noise (LSB^2/12 per sample: 4.79e-3 m/s^2, 1.07e-3 rad/s).
"""
from __future__ import annotations

import dataclasses
import datetime as _dt
import math
from typing import Callable

import numpy as np

from leonav.hardware.clock import utc_unix
from leonav.hardware.imu import witmotion_encode as wenc
from leonav.hardware.imu.witmotion import PACKET_LEN as WITMOTION_PACKET_BYTES
from leonav.hardware.records import NmeaSentence
from leonav.hardware.uart import serialization_s
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gen.profiles import WT901
from leonav_runtime.inputs import ImuTable

UBX_NAV_PVT_FRAME_BYTES = 100 + 8     # payload + sync, class, id, length, checksum
NMEA_LINE_END_BYTES = 2               # CR LF


def utc_of(t_utc_unix: float) -> _dt.datetime:
    try:
        return _dt.datetime.fromtimestamp(t_utc_unix, _dt.timezone.utc)
    except (OverflowError, OSError, ValueError):
        raise UserInputError(f"the session's time axis maps to {t_utc_unix!r} s since 1970: not a UTC time "
                             "(check the GNSS time tags or session.json start_utc)") from None


def device_baud(dec, kind: str) -> int | None:
    """Baud of the session's `kind` device ("gnss", "imu") from session.json, if recorded."""
    for d in dec.session_info.get("devices", []):
        if d.get("kind") == kind and isinstance(d.get("baud"), int) and d["baud"] > 0:
            return d["baud"]
    return None


def tag_serialization_s(dec) -> float:
    """UART time of the time-tag message itself (s): the tag is stamped when its *last* byte
    arrives, so the map is late by at least this much (median over the tags of the map's
    source: RMC/ZDA sentence length + CR LF, or the NAV-PVT frame; `uart.serialization_s`).
    0 when the baud is unknown."""
    baud = device_baud(dec, "gnss")
    src = dec.time_map.source
    if not baud:
        return 0.0
    if src in ("RMC", "ZDA"):
        n = [len(r.text) + NMEA_LINE_END_BYTES for r in dec.gnss_records
             if isinstance(r, NmeaSentence) and r.sentence_type == src]
        return serialization_s(float(np.median(n)), baud) if n else 0.0
    if src == "NAV-PVT":
        return serialization_s(UBX_NAV_PVT_FRAME_BYTES, baud)
    return 0.0


def mono_to_utc_function(dec, gnss_latency_s: float = 0.0) -> tuple[Callable[[np.ndarray], np.ndarray], str]:
    """Monotonic -> UTC POSIX mapping of a decoded session, and a description of its source.

    The session's time map pairs each tag's arrival with the epoch it names, so it maps an
    arrival to a time late by the tag's own serialization (`tag_serialization_s`) plus the
    receiver's output latency (`gnss_latency_s`, given); both are removed here.
    """
    tm = dec.time_map
    if tm.valid:
        late = tag_serialization_s(dec) + gnss_latency_s
        return (lambda t: np.asarray(tm.to_utc_unix(np.asarray(t, float)), float) + late,
                f"GNSS time map from {tm.source} ({tm.n_tags} tags, residual std {tm.residual_std_s * 1e3:.1f} ms), "
                f"shifted by +{late * 1e3:.1f} ms (tag serialization {tag_serialization_s(dec) * 1e3:.1f} ms + "
                f"receiver latency {gnss_latency_s * 1e3:.1f} ms)")
    info = dec.session_info
    if "start_utc" in info and "t_mono_start_s" in info:
        try:
            start = utc_unix(_dt.datetime.fromisoformat(str(info["start_utc"])))
        except (ValueError, OverflowError):
            raise UserInputError(f"{dec.folder / 'session.json'}: start_utc {str(info['start_utc'])[:40]!r}: "
                                 "expected an ISO 8601 UTC time") from None
        t0 = float(info["t_mono_start_s"])
        return (lambda t: start + (np.asarray(t, float) - t0),
                "host wall clock of session.json (no GNSS time tag in gnss.raw): UTC may be off by seconds")
    raise UserInputError(f"{dec.folder}: no GNSS time tags (RMC/ZDA/NAV-PVT) and no start_utc/t_mono_start_s in "
                         "session.json: cannot place the records in time")


def regular_sample_times(t_mono: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Sample times of a regular sensor from jittered arrival stamps.

    Returns (fitted stamps (n,), sample index (n,), number of missing samples).
    Stamps are arrival times, so they are only ever late. A host stall makes several
    samples arrive together: within such a burst only the last one is close to on time.
    The on-time samples are those not followed by another within half a period; between
    two of them, the index advances by round(time span / period), at least by the number
    of samples received (any missing ones are placed just before the later on-time one);
    gaps that read jitter made up are then removed (`_drop_spurious_gaps`). The period
    (median spacing) is then refined, with the offset, by a least-squares line through
    (index, stamp) of the on-time samples after dropping stamps more than max(5 robust
    sigmas, 30 ms) off.
    """
    t = np.asarray(t_mono, float)
    if t.size < 2:
        return t.copy(), np.arange(t.size), 0
    d = np.diff(t)
    period = float(np.median(d[d > 0])) if np.any(d > 0) else 0.1
    on_time = np.append(d >= period / 2, True)
    on_time[0] = True
    anchors = np.flatnonzero(on_time)
    idx = np.zeros(t.size, int)
    for a, b in zip(anchors[:-1], anchors[1:]):
        idx[a + 1:b] = idx[a] + np.arange(1, b - a)
        idx[b] = idx[a] + max(b - a, int(round((t[b] - t[a]) / period)))
    idx = _drop_spurious_gaps(t, idx, period)
    keep = on_time.copy()
    for _ in range(3):
        a, b = np.polyfit(idx[keep], t[keep], 1)
        res = t - (a * idx + b)
        mad = np.median(np.abs(res[keep] - np.median(res[keep])))
        keep = on_time & (np.abs(res) <= max(5 * 1.4826 * mad, 0.03))
    return a * idx + b, idx, int(idx[-1] + 1 - t.size)


def _drop_spurious_gaps(t: np.ndarray, idx: np.ndarray, period: float, window: int = 10) -> np.ndarray:
    """Sample indices without the gaps that read jitter made up.

    Read delays of half a period or more (fast sensors, busy hosts) stretch one spacing
    into what looks like a missing sample. Stamps are only ever late, so the lower envelope
    of t - period * index (the least-delayed stamps of `window` samples) is the same before
    and after a real gap; after a made-up one it drops by a period. Such gaps are removed
    in time order.
    """
    idx = idx.copy()
    for g in np.flatnonzero(np.diff(idx) > 1) + 1:
        before = t[max(0, g - window):g] - period * idx[max(0, g - window):g]
        after = t[g:g + window] - period * idx[g:g + window]
        n_fake = min(int(round((before.min() - after.min()) / period)), int(idx[g] - idx[g - 1] - 1))
        if n_fake > 0:
            idx[g:] -= n_fake
    return idx


def imu_table(samples, to_utc, notes: list[str], imu_baud: int | None = None) -> tuple[ImuTable, float, dict]:
    """IMU table from WitMotion samples; returns (table, epoch UTC POSIX, counts).

    A sample is stamped when its acceleration packet has arrived; with the baud known,
    that packet's serialization (`uart.serialization_s`) is taken off the stamp.
    """
    if len(samples) < 2:
        raise UserInputError(f"imu.raw: {len(samples)} complete WitMotion cycle(s) (acc+gyro+angle); "
                             "need at least 2 to propagate")
    t_fit, idx, missing = regular_sample_times(np.array([s.t_mono_s for s in samples]))
    if imu_baud:
        t_fit = t_fit - serialization_s(WITMOTION_PACKET_BYTES, imu_baud)
    utc = to_utc(t_fit)
    epoch = float(utc[0])
    t = utc - epoch
    w = np.array([s.w_b_radps for s in samples], float)
    f = np.array([s.f_b_mps2 for s in samples], float)
    rpy = np.array([s.rpy_rad for s in samples], float)
    period = float(np.median(np.diff(t)))
    if missing:
        notes.append(f"IMU: {missing} missing sample(s) inside the session; their intervals are bridged with "
                     "the next sample's rates")
    counts = {"imu_samples": len(samples), "imu_missing_samples": missing, "imu_period_s": period}
    # sample 0 only opens the time axis; records start with the interval ending at sample 1
    return ImuTable.from_rates(t[1:], np.diff(t), w[1:], f[1:], rpy[1:]), epoch, counts


def filter_profile(imu_period_s: float, quantized: bool = True):
    """WT901 profile, with the WitMotion quantization noise added to VRW/ARW when `quantized`."""
    if not quantized:
        return WT901
    vrw = math.sqrt(WT901.vrw**2 + wenc.ACC_LSB_MPS2**2 / 12 * imu_period_s)
    arw = math.sqrt(WT901.arw**2 + wenc.GYRO_LSB_RADPS**2 / 12 * imu_period_s)
    return dataclasses.replace(WT901, name="wt901+quantization", vrw=vrw, arw=arw)
