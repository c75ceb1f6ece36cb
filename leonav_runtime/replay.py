"""Replay a recorded session through the generated filter: GPS+IMU, LEO(alpha)+IMU, GPS+LEO(alpha)+IMU.

Pipeline (`replay_session`):
1. `hardware.session.decode_session` re-decodes gnss.raw / imu.raw with their chunk stamps.
2. One time axis: the host monotonic stamps mapped to UTC by the session's GNSS time map
   (RMC/NAV-PVT tags; without tags, the host wall clock of session.json, flagged in
   `notes`). t = 0 is the first IMU sample; every record time is seconds since it.
3. IMU: the WitMotion samples are regular in the sensor's clock, so their times are a
   straight-line fit of the arrival stamps against the sample index (gaps of missing
   cycles are detected from the stamp spacing and counted); the host's read jitter does
   not enter the intervals. A sample's rate and specific force are taken as the means
   over the interval ending at it: increments `w_b*dt`, `f_b*dt` (body FLU, no axis change,
   hardware/README.md). The filter's white noise adds the protocol's quantization
   (LSB^2/12 per sample: 4.79e-3 m/s^2, 1.07e-3 rad/s) to the WT901 profile.
4. GNSS fixes (GGA or NAV-PVT) at the receiver's own UTC of the fix: lat/lon/ellipsoidal
   height -> ENU at the origin (first usable fix, or `origin_deg`); POS_E/N/U records with R
   from GST (lat/lon/alt sigmas) when present, else NAV-PVT hAcc/sqrt(2), vAcc, else
   `DEFAULT_UERE_M * HDOP` per horizontal axis and twice that vertically. A fix without a
   finite latitude, longitude and height (e.g. a GGA with an empty altitude field) is
   neither the origin nor a measurement; such fixes are counted (`gnss_fixes_unusable`).
5. Beacons: `beacons.pipeline.process_capture` on sdr.cu8 with the capture start from its
   monotonic stamp through the time map (the SigMF core:datetime is the host clock);
   each associated epoch becomes a DOPPLER_RATE record. The carrier f_c (of the pipeline's
   predictions and of the filter's model) is the capture's RF centre (SigMF
   leonav:rf_center_hz = core:frequency + leonav:lnb_lo_hz: the recorder tunes the beacon
   to baseband 0); without a readable Ku-band value, `STARLINK_BEACON_HZ` with a note.
   aux = SGP4 ECEF state and acceleration of that satellite at that time and the specific
   force averaged over the last `simulate.F_B_AVERAGE_S` up to the latest IMU sample; R =
   max(sigma_fit, floor)^2 plus that average's accelerometer noise
   (generated `leonav_doppler_rate_variance`), as the simulator does.
6. Initial state: position = the initializing fix (sigma from its R), velocity = RMC
   speed/course or NAV-PVT velocity (0 when absent), roll/pitch = the sensor's angle output
   averaged over the first second, yaw = `yaw_deg` if given, else the sensor's yaw (its own
   reference: magnetic North in 9-axis mode, power-up heading in 6-axis mode, so give
   `yaw_deg` from East towards North for real sessions), biases 0; P0 from
   `simulate.prior_sigmas`. The initializing fix is the first usable one from
   `INIT_FIX_WINDOW_S` before the first IMU sample on. If it comes more than
   `INIT_FIX_MAX_DELAY_S` after the start of the first IMU interval, the filter starts at
   the fix instead (a moving receiver is not given a late position): earlier IMU intervals
   are dropped (counted, `imu_records_before_start`) and the one spanning the fix is cut at it.
7. Reference: truth.csv when present (synthetic sessions), else the GNSS fixes (position
   only; then GPS+IMU is compared with its own input, which flatters it).
"""
from __future__ import annotations

import csv
import dataclasses
import datetime as _dt
import json
import math
import time
import warnings
from pathlib import Path
from typing import Callable

import numpy as np

from leonav_runtime import filter as lfilter
from leonav_runtime import geometry, navfuncs, records, simulate
from leonav_runtime.errors import UserInputError
from leonav_runtime.output import write_csv, write_json
from leonav_runtime.gen.constants import KU_DOWNLINK_MAX_HZ, KU_DOWNLINK_MIN_HZ, STARLINK_BEACON_HZ

MODES = ("gps+imu", "leo-alpha+imu", "gps+leo-alpha+imu")
MODE_USES = {"gps+imu": ("fix",), "leo-alpha+imu": ("alpha",), "gps+leo-alpha+imu": ("fix", "alpha")}
DEFAULT_UERE_M = 1.5            # per-axis horizontal sigma per unit HDOP when no GST/NAV-PVT accuracy
ALPHA_SIGMA_FLOOR_HZ_S = 0.5    # the fit sigma can be optimistic for short ridges
KU_DOWNLINK_HZ = (KU_DOWNLINK_MIN_HZ, KU_DOWNLINK_MAX_HZ)  # a capture RF centre outside is not a beacon carrier
INIT_WINDOW_S = 1.0             # samples averaged for the initial roll/pitch
INIT_FIX_WINDOW_S = 0.2         # a fix this much before the first IMU sample still initializes
# A fix up to this long after the filter's start initializes it there (position error at most
# this times the speed: 0.5 m at 10 m/s, below a consumer fix's noise); a later first fix
# moves the start to the fix. Receivers at 1-10 Hz give their first fix within a second of a
# warm start, so a real session loses at most that much IMU data.
INIT_FIX_MAX_DELAY_S = 0.05
VEL_SIGMA0_MPS = 0.5
ROLL_PITCH_SIGMA0_RAD = math.radians(0.5)
YAW_SIGMA0_GIVEN_RAD = math.radians(2.0)
YAW_SIGMA0_SENSOR_RAD = math.radians(5.0)


@dataclasses.dataclass
class ReplayOptions:
    modes: tuple[str, ...] = MODES
    origin_deg: tuple[float, float, float] | None = None   # lat deg, lon deg, ellipsoidal height m
    yaw_deg: float | None = None                           # initial heading, from East towards North
    alpha_sigma_floor_hz_s: float = ALPHA_SIGMA_FLOOR_HZ_S
    gate_nis: float = lfilter.CHI2_1DOF_999
    use_truth: bool = True
    gnss_latency_s: float = 0.0     # receiver output latency (epoch -> first byte), if measured (PPS)


@dataclasses.dataclass
class FixTable:
    """GNSS fixes on the replay time axis: t (s), enu (m, at the origin), sigma (m, E N U),
    vel_en (m/s, NaN when unknown)."""

    t: np.ndarray
    enu: np.ndarray
    sigma: np.ndarray
    vel_en: np.ndarray

    @classmethod
    def empty(cls) -> "FixTable":
        return cls(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 2)))


@dataclasses.dataclass
class AlphaTable:
    """Doppler-rate measurements: t (s), norad id, index in the element set, z (Hz/s), sigma (Hz/s)."""

    t: np.ndarray
    norad: np.ndarray
    sat_index: np.ndarray
    z: np.ndarray
    sigma: np.ndarray

    @classmethod
    def empty(cls) -> "AlphaTable":
        z = np.zeros(0)
        return cls(z, z.astype(int), z.astype(int), z, z)


@dataclasses.dataclass
class ImuTable:
    """IMU records' inputs: t (s, end of each interval), dt (s), w_b (rad/s), f_b (m/s^2),
    and the sensor's angles rpy (rad) of the same samples."""

    t: np.ndarray
    dt: np.ndarray
    w_b: np.ndarray
    f_b: np.ndarray
    rpy: np.ndarray


@dataclasses.dataclass
class SessionInputs:
    """Everything the filter runs on, on one time axis (s since epoch_utc)."""

    epoch_utc: _dt.datetime
    origin: tuple[float, float, float]      # rad, rad, m
    imu: ImuTable
    fixes: FixTable
    alpha: AlphaTable
    x0: np.ndarray
    P0: np.ndarray
    params: np.ndarray
    records: dict[str, np.ndarray]          # "imu", "fix", "alpha"
    carrier_hz: float = STARLINK_BEACON_HZ  # beacon carrier f_c of the Doppler-rate model
    notes: list[str] = dataclasses.field(default_factory=list)
    skipped: dict[str, str] = dataclasses.field(default_factory=dict)   # mode -> reason
    counts: dict = dataclasses.field(default_factory=dict)
    init: dict = dataclasses.field(default_factory=dict)
    beacons: dict = dataclasses.field(default_factory=dict)


@dataclasses.dataclass
class Reference:
    """Reference on the replay axis: t (s), p_enu (m), v_enu (m/s) or None, q_nb or None."""

    kind: str
    t: np.ndarray
    p_enu: np.ndarray
    v_enu: np.ndarray | None
    q_nb: np.ndarray | None


# ------------------------------------------------------------------ time axis


def utc_of(t_utc_unix: float) -> _dt.datetime:
    return _dt.datetime.fromtimestamp(t_utc_unix, _dt.timezone.utc)


def _device_baud(dec, kind: str) -> int | None:
    for d in dec.session_info.get("devices", []):
        if d.get("kind") == kind and isinstance(d.get("baud"), int) and d["baud"] > 0:
            return d["baud"]
    return None


def tag_serialization_s(dec) -> float:
    """UART time of the time-tag message itself (s): the tag is stamped when its *last* byte
    arrives, so the map is late by at least this much (median over the tags of the map's
    source: RMC/ZDA sentence length + CR LF, or the 100-byte NAV-PVT frame + 8 framing
    bytes, at 10 bits per byte). 0 when the baud is unknown."""
    from hardware.records import NmeaSentence

    baud = _device_baud(dec, "gnss")
    src = dec.time_map.source
    if not baud:
        return 0.0
    if src in ("RMC", "ZDA"):
        n = [len(r.text) + 2 for r in dec.gnss_records if isinstance(r, NmeaSentence) and r.sentence_type == src]
        return float(np.median(n)) * 10 / baud if n else 0.0
    if src == "NAV-PVT":
        return 108 * 10 / baud
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
        from hardware.clock import utc_unix

        start = utc_unix(_dt.datetime.fromisoformat(info["start_utc"]))
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
    gaps that read jitter made up are then removed (`_drop_spurious_gaps`). The period (median spacing) is then refined, with the offset, by a least-squares line
    through (index, stamp) of the on-time samples after dropping stamps more than
    max(5 robust sigmas, 30 ms) off.
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


# ------------------------------------------------------------------ decoding to tables


def imu_table(samples, to_utc, notes: list[str], imu_baud: int | None = None) -> tuple[ImuTable, float, dict]:
    """IMU table from WitMotion samples; returns (table, epoch UTC POSIX, counts).

    A sample is stamped when its 11-byte acceleration packet has arrived; with the baud
    known, that packet's serialization (110 bits) is taken off the stamp.
    """
    if len(samples) < 2:
        raise UserInputError(f"imu.raw: {len(samples)} complete WitMotion cycle(s) (acc+gyro+angle); "
                             "need at least 2 to propagate")
    t_fit, idx, missing = regular_sample_times(np.array([s.t_mono_s for s in samples]))
    if imu_baud:
        t_fit = t_fit - 110.0 / imu_baud
    utc = to_utc(t_fit)
    epoch = float(utc[0])
    t = utc - epoch
    w = np.array([s.w_b_radps for s in samples], float)
    f = np.array([s.f_b_mps2 for s in samples], float)
    rpy = np.array([s.euler_rad for s in samples], float)
    period = float(np.median(np.diff(t)))
    if missing:
        notes.append(f"IMU: {missing} missing sample(s) inside the session; their intervals are bridged with "
                     "the next sample's rates")
    counts = {"imu_samples": len(samples), "imu_missing_samples": missing, "imu_period_s": period}
    # sample 0 only opens the time axis; records start with the interval ending at sample 1
    return ImuTable(t[1:], np.diff(t), w[1:], f[1:], rpy[1:]), epoch, counts


def _tod_key(t: _dt.time | _dt.datetime) -> int:
    """Time of day in hundredths of a second (matches GGA/RMC/GST of one epoch)."""
    return round((t.hour * 3600 + t.minute * 60 + t.second + t.microsecond * 1e-6) * 100)


def fix_height_m(fix) -> float | None:
    """Ellipsoidal height of a fix (m): its own, else its height above mean sea level (no geoid
    separation sent), None when neither is a finite number (e.g. a GGA with an empty altitude)."""
    for h in (fix.height_m, fix.hmsl_m):
        if h is not None and math.isfinite(h):
            return float(h)
    return None


def usable_fix(fix) -> bool:
    """A fix with finite latitude, longitude and height: it can be the origin and a measurement."""
    return (fix.lat_rad is not None and fix.lon_rad is not None and math.isfinite(fix.lat_rad)
            and math.isfinite(fix.lon_rad) and fix_height_m(fix) is not None)


def _positive_finite(v) -> bool:
    return v is not None and math.isfinite(v) and v > 0


def fix_table(gnss_records, to_utc, epoch: float, origin, notes: list[str]) -> tuple[FixTable, dict]:
    """Fixes on the replay axis in ENU at `origin` (rad, rad, m) with their 1-sigma.

    Fixes without a finite position (`usable_fix`) are left out and counted."""
    from hardware.records import GnssFix, NmeaSentence

    gst, rmc = {}, {}
    for r in gnss_records:
        if isinstance(r, NmeaSentence) and r.msg is not None:
            try:
                if r.sentence_type == "GST" and r.msg.timestamp is not None:
                    gst[_tod_key(r.msg.timestamp)] = (float(r.msg.std_dev_latitude), float(r.msg.std_dev_longitude),
                                                      float(r.msg.std_dev_altitude))
                elif r.sentence_type == "RMC" and r.msg.timestamp is not None and r.msg.status == "A":
                    speed = float(r.msg.spd_over_grnd or 0.0) * 1852.0 / 3600.0
                    course = math.radians(float(r.msg.true_course or 0.0))
                    rmc[_tod_key(r.msg.timestamp)] = (speed * math.sin(course), speed * math.cos(course))
            except (TypeError, ValueError):
                continue          # an empty field: this epoch has no GST/RMC information
    fixes = [r for r in gnss_records if isinstance(r, GnssFix)]
    usable = [f for f in fixes if usable_fix(f)]
    counts = {"gnss_fixes": len(fixes), "gnss_fixes_unusable": len(fixes) - len(usable), "fix_sigma_source": {}}
    if len(usable) < len(fixes):
        notes.append(f"GNSS: {len(fixes) - len(usable)} fix(es) without a finite latitude, longitude and height "
                     "(e.g. an empty GGA altitude field) left out")
    fixes = usable
    if not fixes:
        return FixTable.empty(), counts
    lat0, lon0, h0 = origin
    r0 = geometry.geodetic_to_ecef(lat0, lon0, h0)
    t, enu, sig, vel = [], [], [], []
    no_height = 0
    for f in fixes:
        t_utc = f.utc.timestamp() if f.utc is not None else float(to_utc(f.t_mono_s))
        h = fix_height_m(f)
        no_height += f.height_m is None or not math.isfinite(f.height_m)
        enu.append(geometry.ecef_to_enu(geometry.geodetic_to_ecef(f.lat_rad, f.lon_rad, h), r0, lat0, lon0))
        t.append(t_utc - epoch)
        key = _tod_key(f.utc) if f.utc is not None else None
        if key in gst and all(math.isfinite(v) and v > 0 for v in gst[key]):
            s_n, s_e, s_u = gst[key]
            src = "GST"
        elif _positive_finite(f.h_acc_m) and _positive_finite(f.v_acc_m):
            s_e = s_n = f.h_acc_m / math.sqrt(2.0)
            s_u = f.v_acc_m
            src = "NAV-PVT accuracy"
        else:
            hdop = f.hdop if _positive_finite(f.hdop) else 1.0
            s_e = s_n = DEFAULT_UERE_M * hdop
            s_u = 2.0 * s_e
            src = f"{DEFAULT_UERE_M:g} m x HDOP"
        counts["fix_sigma_source"][src] = counts["fix_sigma_source"].get(src, 0) + 1
        sig.append([max(s_e, 0.1), max(s_n, 0.1), max(s_u, 0.1)])
        if f.vel_ned_mps is not None:
            vel.append([f.vel_ned_mps[1], f.vel_ned_mps[0]])
        else:
            vel.append(list(rmc.get(key, (math.nan, math.nan))))
    if no_height:
        notes.append(f"GNSS: {no_height} fix(es) without geoid separation: height above mean sea level used as "
                     "ellipsoidal height (tens of metres off in Up)")
    return FixTable(np.array(t), np.array(enu), np.array(sig), np.array(vel)), counts


def _sigmf_mono_start(folder: Path) -> float | None:
    meta = folder / "sdr.sigmf-meta"
    if not meta.is_file():
        return None
    try:
        glob = json.loads(meta.read_text()).get("global", {})
    except json.JSONDecodeError:
        return None          # open_capture reports the bad metadata with its line
    v = glob.get("leonav:t_mono_start_s")
    return float(v) if isinstance(v, (int, float)) else None


def capture_carrier(info) -> tuple[float, str]:
    """Beacon carrier f_c (Hz) of a capture and where it came from.

    `leonav record` tunes the beacon to baseband 0, so f_c is the capture's RF centre
    (`CaptureInfo.rf_center_hz`: SigMF leonav:rf_center_hz = core:frequency +
    leonav:lnb_lo_hz). A value outside the Ku downlink band (`KU_DOWNLINK_HZ`, e.g. a
    capture without an LNB LO) falls back to `STARLINK_BEACON_HZ`."""
    rf = float(info.rf_center_hz)
    if math.isfinite(rf) and KU_DOWNLINK_HZ[0] <= rf <= KU_DOWNLINK_HZ[1]:
        return rf, f"capture metadata ({info.source or info.path}: RF centre = tuned frequency + LNB LO)"
    return STARLINK_BEACON_HZ, (f"default {STARLINK_BEACON_HZ / 1e9:g} GHz: the capture's RF centre "
                                f"{rf / 1e9:.6g} GHz (tuned {info.center_freq_hz / 1e9:.6g} GHz + LNB LO "
                                f"{info.lnb_lo_hz / 1e9:.6g} GHz) is outside the Ku downlink band "
                                f"{KU_DOWNLINK_HZ[0] / 1e9:g}-{KU_DOWNLINK_HZ[1] / 1e9:g} GHz")


def _default_carrier(reason: str) -> dict:
    return {"carrier_hz": STARLINK_BEACON_HZ,
            "carrier_source": f"default {STARLINK_BEACON_HZ / 1e9:g} GHz: {reason}"}


def beacon_table(folder: Path, out_dir: Path | None, to_utc, time_source_ok: bool, epoch: float, origin,
                 elements, notes: list[str], progress=None) -> tuple[AlphaTable, dict, object]:
    """Run the beacon pipeline on the session's capture; returns (table, summary, elements).

    summary["carrier_hz"], ["carrier_source"]: the carrier f_c (`capture_carrier`, else the default)."""
    from leonav_runtime.beacons import capture_io, pipeline
    from leonav_runtime.beacons.predict import Site

    data = folder / "sdr.cu8"
    if not data.exists():
        return AlphaTable.empty(), {"reason_empty": "no sdr.cu8 in the session"} | _default_carrier(
            "no capture in the session"), elements
    try:
        info = capture_io.open_capture(data)
    except UserInputError as exc:
        return AlphaTable.empty(), {"reason_empty": str(exc)} | _default_carrier(
            f"capture metadata unreadable ({exc})"), elements
    carrier_hz, carrier_src = capture_carrier(info)
    carrier = {"carrier_hz": carrier_hz, "carrier_source": carrier_src}
    mono = _sigmf_mono_start(folder)
    if mono is not None and time_source_ok:
        info.start_utc = utc_of(float(to_utc(mono)))
        start_src = "leonav:t_mono_start_s through the GNSS time map"
    else:
        start_src = "SigMF core:datetime (host wall clock)"
        notes.append("beacons: capture start from the host wall clock (no monotonic stamp or no GNSS time map)")
    if info.start_utc is None:
        return AlphaTable.empty(), {"reason_empty": f"{data}: capture start time unknown"} | carrier, elements
    if elements is None:
        from leonav_runtime.session_synth import builtin_starlink

        elements = builtin_starlink(info.start_utc)
        notes.append("beacons: no --tle given: built-in Walker Starlink constellation at the UTC minute nearest the "
                     "capture start (right for synthetic sessions only; give real element sets for a real capture)")
    site = Site(*origin)
    cfg = pipeline.PipelineConfig(tone_rf_hz=carrier_hz, band_hz=min(1.2e6, info.sample_rate_hz))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = pipeline.process_capture(info, elements, site, cfg, progress)
    for w in {str(w.message) for w in caught}:
        notes.append(f"beacons: {w}")
    if out_dir is not None:
        pipeline.write_outputs(res, out_dir / "beacons")
    summ = pipeline.summary(res)
    summary = {"capture_start_utc": info.start_utc, "capture_start_source": start_src,
               "counts": summ["counts"], "rate_residual_abs_hz_s": summ["rate_residual_abs_hz_s"],
               "reason_empty": summ["reason_empty"], **carrier,
               "associations": [{k: a[k] for k in ("ridge_id", "status", "norad_id", "name", "reason")}
                                for a in summ["associations"]]}
    t0 = info.start_utc.timestamp() - epoch
    rows = []
    for ridge, m, a in zip(res.ridges, res.measurements, res.associations):
        if a.status != "associated" or m.t_s.size == 0:
            continue
        idx = int(res.predictions.sat_index[a.sat_row])
        for k in range(m.t_s.size):
            rows.append((t0 + m.t_s[k], a.norad_id, idx, m.rate_hz_s[k], m.sigma_rate_hz_s[k]))
    rows.sort()
    if not rows:
        return AlphaTable.empty(), summary, elements
    arr = list(zip(*rows))
    return (AlphaTable(np.array(arr[0]), np.array(arr[1], int), np.array(arr[2], int), np.array(arr[3]),
                       np.array(arr[4])), summary, elements)


# ------------------------------------------------------------------ inputs -> records, x0, P0


def filter_profile(imu_period_s: float, quantized: bool = True):
    """WT901 profile, with the WitMotion quantization noise added to VRW/ARW when `quantized`."""
    from hardware.imu import witmotion_encode as wenc
    from leonav_runtime.gen.profiles import WT901

    if not quantized:
        return WT901
    vrw = math.sqrt(WT901.vrw**2 + wenc.ACC_LSB_MPS2**2 / 12 * imu_period_s)
    arw = math.sqrt(WT901.arw**2 + wenc.GYRO_LSB_RADPS**2 / 12 * imu_period_s)
    return dataclasses.replace(WT901, name="wt901+quantization", vrw=vrw, arw=arw)


def _circular_mean(a: np.ndarray) -> float:
    return float(np.arctan2(np.mean(np.sin(a)), np.mean(np.cos(a))))


def imu_from(imu: ImuTable, t_start: float) -> tuple[ImuTable, int]:
    """The IMU table from `t_start` (s) on: intervals ending at or before it dropped (their number
    is returned), the one spanning it cut at it (its mean rates kept, so its increments shrink)."""
    keep = imu.t > t_start
    out = ImuTable(imu.t[keep], imu.dt[keep].copy(), imu.w_b[keep], imu.f_b[keep], imu.rpy[keep])
    if out.t.size:
        out.dt[0] = min(out.dt[0], out.t[0] - t_start)
    return out, int((~keep).sum())


def _start_and_init_fix(imu: ImuTable, fixes: FixTable, notes: list[str]) -> tuple[float, int]:
    """(filter start time s, index of the initializing fix or -1); module doc, step 6."""
    t_first = float(imu.t[0] - imu.dt[0])
    cand = np.flatnonzero(fixes.t >= t_first - INIT_FIX_WINDOW_S)
    if cand.size == 0:
        return t_first, -1
    k = int(cand[0])
    t_fix = float(fixes.t[k])
    if t_fix <= t_first + INIT_FIX_MAX_DELAY_S:
        return t_first, k
    if t_fix >= imu.t[-1]:
        notes.append(f"init: the first usable GNSS fix (t={t_fix:.3f} s) comes after the last IMU sample "
                     f"(t={imu.t[-1]:.3f} s): the position starts at the origin")
        return t_first, -1
    notes.append(f"init: the first usable GNSS fix comes {t_fix - t_first:.3f} s after the first IMU interval's "
                 f"start (more than {INIT_FIX_MAX_DELAY_S:g} s): the filter starts at that fix, earlier IMU data "
                 "dropped")
    return t_fix, k


def assemble(epoch_utc: _dt.datetime, origin, imu: ImuTable, fixes: FixTable, alpha: AlphaTable, elements,
             options: ReplayOptions, profile, nav: navfuncs.NavFunctions,
             notes: list[str] | None = None, carrier_hz: float = STARLINK_BEACON_HZ) -> SessionInputs:
    """Records, initial state and covariance, parameters (shared by replay and the direct simulation).

    Times in s since `epoch_utc`; origin (rad, rad, m); carrier_hz: beacon carrier f_c (Hz).
    The filter starts at the start of the first IMU interval or, when the initializing fix
    comes later than `INIT_FIX_MAX_DELAY_S` after it, at that fix (module doc, step 6).
    """
    from leonav_runtime.params import build_params

    notes = list(notes or [])
    L = nav.layout
    lat0, lon0, h0 = origin
    params = np.array(build_params(lat0, lon0, h0, imu=profile, q_blo=simulate.LO_RANDOM_WALK_HZ2_S,
                                   f_c_hz=carrier_hz))
    if not np.all(np.isfinite(params)):
        raise UserInputError(f"replay: non-finite filter parameters from origin (lat, lon rad, h m) {origin}, "
                             f"carrier {carrier_hz} Hz, IMU profile {profile.name}: expected finite numbers")
    nav.params = params

    # The initializing fix sets the state and is not applied again as a measurement (its
    # error would count twice).
    t_first = float(imu.t[0] - imu.dt[0])
    t_start, init_fix = _start_and_init_fix(imu, fixes, notes)
    imu, n_before = imu_from(imu, t_start)
    t_end = float(imu.t[-1])
    rec_imu = records.imu_records(imu.t, imu.w_b * imu.dt[:, None], imu.f_b * imu.dt[:, None], imu.dt)

    inside = (fixes.t >= t_start) & (fixes.t <= t_end)
    if init_fix >= 0:
        inside[init_fix] = False
    counts = {"imu_records_before_start": n_before,
              "fixes_outside_imu_span": int((~inside).sum()) - (init_fix >= 0)}
    fx = FixTable(fixes.t[inside], fixes.enu[inside], fixes.sigma[inside], fixes.vel_en[inside])
    parts = [records.measurement_records(fx.t, nav.kind_id(k), fx.enu[:, i], fx.sigma[:, i] ** 2)
             for i, k in enumerate(("pos_e", "pos_n", "pos_u"))] if fx.t.size else []
    rec_fix = records.merge_records(*parts) if parts else np.zeros(0, records.RECORD_DTYPE)

    inside = (alpha.t >= t_start) & (alpha.t <= t_end)
    counts["alpha_outside_imu_span"] = int((~inside).sum())
    al = AlphaTable(alpha.t[inside], alpha.norad[inside], alpha.sat_index[inside], alpha.z[inside],
                    alpha.sigma[inside])
    rec_alpha = np.zeros(0, records.RECORD_DTYPE)
    if al.t.size:
        from leonav_runtime.orbits import propagate_ecef

        aux = np.zeros((al.t.size, L.NAUX))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")     # staleness is reported by the beacon step
            for idx in np.unique(al.sat_index):
                sel = al.sat_index == idx
                st = propagate_ecef(elements.select([int(idx)]), epoch_utc, al.t[sel])
                aux[sel, L.AUX_R_S_ECEF:L.AUX_R_S_ECEF + 3] = st.r_ecef_m[0]
                aux[sel, L.AUX_V_S_ECEF:L.AUX_V_S_ECEF + 3] = st.v_ecef_mps[0]
                aux[sel, L.AUX_A_S_ECEF:L.AUX_A_S_ECEF + 3] = st.a_ecef_mps2[0]
        # Receiver acceleration input: the specific force averaged up to the latest IMU sample
        # (row 0 = the start, row j+1 = sample imu.t[j]); R carries that average's noise.
        f_b_avg, f_b_span_s = simulate.averaged_specific_force(imu.f_b * imu.dt[:, None], imu.dt)
        k = np.clip(np.searchsorted(imu.t, al.t + 1e-9) - 1, -1, imu.t.size - 1)
        aux[:, L.AUX_F_B:L.AUX_F_B + 3] = f_b_avg[k + 1]
        sigma = np.maximum(al.sigma, options.alpha_sigma_floor_hz_s)
        R = nav.doppler_rate_variance(sigma, f_b_span_s, params)
        rec_alpha = records.measurement_records(al.t, nav.kind_id("doppler_rate"), al.z, R, aux, al.norad)
        counts["alpha_f_b_average_s"] = f_b_span_s

    # initial state
    x0 = np.zeros(L.NX)
    init: dict = {"start_s": t_start}
    if init_fix >= 0:
        x0[L.X_P_ENU:L.X_P_ENU + 3] = fixes.enu[init_fix]
        pos_sigma = fixes.sigma[init_fix]
        init["position"] = f"fix at t={fixes.t[init_fix]:.3f} s (not applied again as a measurement)"
        v = fixes.vel_en[init_fix]
        if np.all(np.isfinite(v)):
            x0[L.X_V_ENU:L.X_V_ENU + 2] = v
            init["velocity"] = "initializing fix's RMC speed/course (NAV-PVT velocity), vertical 0"
        else:
            init["velocity"] = "0 (no velocity in the initializing fix)"
    else:
        pos_sigma = np.full(3, 10.0)
        init["position"] = "origin (no fix)"
        init["velocity"] = "0"
    init["start"] = (f"the initializing fix ({n_before} IMU interval(s) before it dropped, the next one cut)"
                     if t_start > t_first else "start of the first IMU interval")
    first = imu.t <= imu.t[0] + INIT_WINDOW_S
    roll, pitch = _circular_mean(imu.rpy[first, 0]), _circular_mean(imu.rpy[first, 1])
    f_mean = imu.f_b[first].mean(axis=0)
    level = nav.level(f_mean)
    if options.yaw_deg is not None:
        yaw, yaw_sig, yaw_src = math.radians(options.yaw_deg), YAW_SIGMA0_GIVEN_RAD, "--yaw-deg"
    else:
        yaw, yaw_sig = _circular_mean(imu.rpy[first, 2]), YAW_SIGMA0_SENSOR_RAD
        yaw_src = "WitMotion angle output (the sensor's own yaw reference)"
    x0[L.X_Q_NB:L.X_Q_NB + 4] = nav.quat_from_euler(np.array([roll, pitch, yaw]))[0]
    sig0 = simulate.prior_sigmas(L, profile, pos_sigma, VEL_SIGMA0_MPS,
                                 [ROLL_PITCH_SIGMA0_RAD, ROLL_PITCH_SIGMA0_RAD, yaw_sig])
    init |= {"roll_pitch": f"WitMotion angle output averaged over the first {INIT_WINDOW_S:g} s",
             "yaw": yaw_src, "rpy_deg": np.degrees([roll, pitch, yaw]),
             "accelerometer_leveling_roll_pitch_deg": np.degrees(level),
             "sigma0": {"position_m": pos_sigma, "velocity_mps": VEL_SIGMA0_MPS,
                        "roll_pitch_deg": math.degrees(ROLL_PITCH_SIGMA0_RAD), "yaw_deg": math.degrees(yaw_sig)},
             "imu_profile": {"name": profile.name, "vrw": profile.vrw, "arw": profile.arw}}
    counts |= {"imu_records": int(rec_imu.size), "fix_epochs": int(fx.t.size), "alpha_records": int(rec_alpha.size),
               "alpha_satellites": int(np.unique(al.norad).size)}
    return SessionInputs(epoch_utc=epoch_utc, origin=origin, imu=imu, fixes=fx, alpha=al, x0=x0,
                         P0=np.diag(sig0**2), params=params,
                         records={"imu": rec_imu, "fix": rec_fix, "alpha": rec_alpha}, carrier_hz=carrier_hz,
                         notes=notes, counts=counts, init=init)


def skip_reasons(inputs: SessionInputs, modes) -> dict[str, str]:
    """Modes that cannot run on these inputs, with the reason."""
    out = {}
    for mode in modes:
        if "fix" in MODE_USES[mode] and inputs.records["fix"].size == 0:
            out[mode] = "no GNSS fix inside the IMU time span"
        elif "alpha" in MODE_USES[mode] and inputs.records["alpha"].size == 0:
            out[mode] = "no associated Doppler-rate measurement: " + str(
                inputs.beacons.get("reason_empty") or "no ridge was associated with a satellite")
    return out


# ------------------------------------------------------------------ running and scoring


def run_modes(inputs: SessionInputs, modes, gate_nis: float, nav: navfuncs.NavFunctions) -> dict:
    """{mode: (records, RunResult, seconds)} for every mode not in inputs.skipped."""
    out = {}
    for mode in modes:
        if mode in inputs.skipped:
            continue
        recs = records.merge_records(inputs.records["imu"], *(inputs.records[u] for u in MODE_USES[mode]))
        ekf = lfilter.EKF(inputs.x0, inputs.P0, inputs.params, gate=gate_nis or None, library=nav.library)
        t0 = time.perf_counter()
        res = ekf.run(recs)
        out[mode] = (recs, res, time.perf_counter() - t0)
    return out


def _interp_rows(t_ref: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.column_stack([np.interp(t, t_ref, values[:, j]) for j in range(values.shape[1])])


def truth_reference(path: Path, epoch_utc: _dt.datetime, origin, nav: navfuncs.NavFunctions) -> Reference:
    """truth.csv (utc, geodetic, ENU velocity at the row's position, Euler) on the replay axis and frame."""
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    need = ("utc_unix_s", "lat_deg", "lon_deg", "h_m", "v_e_mps", "v_n_mps", "v_u_mps", "roll_rad", "pitch_rad",
            "yaw_rad")
    if not rows or any(k not in rows[0] for k in need):
        raise UserInputError(f"{path}: expected a header with {', '.join(need)} and at least one row")
    try:
        a = np.array([[float(r[k]) for k in need] for r in rows])
    except ValueError as exc:
        raise UserInputError(f"{path}: non-numeric value ({exc})") from None
    lat0, lon0, h0 = origin
    t = a[:, 0] - epoch_utc.timestamp()
    r = geometry.geodetic_to_ecef(np.radians(a[:, 1]), np.radians(a[:, 2]), a[:, 3])
    p = geometry.ecef_to_enu(r, geometry.geodetic_to_ecef(lat0, lon0, h0), lat0, lon0)
    v_ecef = np.einsum("nji,nj->ni", geometry.C_enu_ecef(np.radians(a[:, 1]), np.radians(a[:, 2])), a[:, 4:7])
    v = v_ecef @ geometry.C_enu_ecef(lat0, lon0).T
    euler = np.column_stack([a[:, 7], a[:, 8], np.unwrap(a[:, 9])])
    return Reference("truth.csv", t, p, v, euler)


def fix_reference(fixes: FixTable) -> Reference:
    return Reference("GNSS fixes", fixes.t, fixes.enu, None, None)


def evaluate(inputs: SessionInputs, runs: dict, ref: Reference | None, nav: navfuncs.NavFunctions) -> dict:
    """Errors per mode on the evaluation grid: {mode: dict(t, err (n, 9), x (n, NX), sigma (n, 9))}."""
    L = nav.layout
    out = {}
    for mode, (recs, res, _) in runs.items():
        if ref is None:
            t_eval = inputs.imu.t
        elif ref.q_nb is not None:   # truth: every IMU time inside the truth's span
            t_eval = inputs.imu.t[(inputs.imu.t >= ref.t[0]) & (inputs.imu.t <= ref.t[-1])]
        else:                        # fixes: at the fix times
            t_eval = ref.t[(ref.t >= inputs.imu.t[0]) & (ref.t <= inputs.imu.t[-1])]
        rows = np.searchsorted(recs["t"], t_eval + 1e-9, side="left") - 1
        ok = rows >= 0
        t_eval, rows = t_eval[ok], rows[ok]
        x = res.x[rows]
        err = np.full((t_eval.size, 9), np.nan)
        if ref is not None and t_eval.size:
            if ref.q_nb is not None:
                x_ref = np.zeros_like(x)
                x_ref[:, 0:3] = _interp_rows(ref.t, ref.p_enu, t_eval)
                x_ref[:, 3:6] = _interp_rows(ref.t, ref.v_enu, t_eval)
                x_ref[:, L.X_Q_NB:L.X_Q_NB + 4] = nav.quat_from_euler(_interp_rows(ref.t, ref.q_nb, t_eval))
                x_ref[:, L.X_Q_NB + 4:] = x[:, L.X_Q_NB + 4:]
                err = np.atleast_2d(nav.boxminus(x, x_ref))[:, :9]
            else:
                k = np.searchsorted(ref.t, t_eval)
                k = np.clip(k, 0, ref.t.size - 1)
                err[:, 0:3] = x[:, 0:3] - ref.p_enu[k]
        out[mode] = {"t": t_eval, "err": err, "x": x, "sigma": np.sqrt(res.P_diag[rows][:, :9])}
    return out


def _rmse(e: np.ndarray) -> float | None:
    if e.size == 0 or np.all(np.isnan(e)):
        return None
    return float(np.sqrt(np.nanmean(np.sum(e**2, axis=1))))


def mode_metrics(runs: dict, scored: dict, nav: navfuncs.NavFunctions) -> dict:
    """Per mode: RMSE (position, horizontal, vertical, velocity, attitude), final errors, record counts."""
    names = {v: k for k, v in nav.library.meas_ids.items()}
    out = {}
    for mode, (recs, res, seconds) in runs.items():
        s = scored[mode]
        e = s["err"]
        per_kind = {}
        for kind in np.unique(res.kind[res.kind >= 0]):
            sel = res.kind == kind
            nis = res.nis[sel & (res.status <= 1)]
            per_kind[names.get(int(kind), str(kind))] = {
                "records": int(sel.sum()), "applied": int(np.sum(res.status[sel] == 0)),
                "gated": int(np.sum(res.status[sel] == 1)), "failed": int(np.sum(res.status[sel] == 2)),
                "nis_mean": float(np.mean(nis)) if nis.size else None}
        att = e[:, 6:9] * 180 / math.pi
        out[mode] = {
            "rmse_position_m": _rmse(e[:, 0:3]), "rmse_horizontal_m": _rmse(e[:, 0:2]),
            "rmse_vertical_m": _rmse(e[:, 2:3]), "rmse_velocity_mps": _rmse(e[:, 3:6]),
            "rmse_attitude_deg": _rmse(att),
            "final_position_error_m": float(np.linalg.norm(e[-1, 0:3])) if e.size and np.all(np.isfinite(e[-1, 0:3])) else None,
            "eval_points": int(s["t"].size),
            "records": {"imu": res.n_imu, "applied": res.n_applied, "gated": res.n_gated, "failed": res.n_failed},
            "per_observable": per_kind, "filter_seconds": seconds,
        }
    return out


# ------------------------------------------------------------------ whole replay


def check_options(options: ReplayOptions) -> ReplayOptions:
    """The options, or a UserInputError naming the bad one."""
    bad = [m for m in options.modes if m not in MODES]
    if bad:
        raise UserInputError(f"--modes: {bad[0]!r}: expected some of {', '.join(MODES)}")
    if options.origin_deg is not None and not all(math.isfinite(v) for v in options.origin_deg):
        raise UserInputError(f"--origin: {options.origin_deg}: expected finite LAT LON H")
    return options


def decode_inputs(folder: Path, options: ReplayOptions, elements=None, out_dir: Path | None = None,
                  nav: navfuncs.NavFunctions | None = None, progress=None) -> SessionInputs:
    """Decode a session folder into SessionInputs (see the module doc, steps 1-6)."""
    from hardware.session import decode_session

    check_options(options)
    nav = nav or navfuncs.NavFunctions()
    folder = Path(folder)
    dec = decode_session(folder)
    notes: list[str] = []
    if not (folder / "imu.raw").exists():
        raise UserInputError(f"{folder}: no imu.raw: every replay mode propagates with the IMU")
    if not dec.imu_samples:
        raise UserInputError(f"{folder / 'imu.raw'}: no complete WitMotion cycle decoded "
                             f"(rejected: {dec.imu_summary.get('rejected')})")
    to_utc, time_src = mono_to_utc_function(dec, options.gnss_latency_s)
    if not dec.time_map.valid:
        notes.append(f"time: {time_src}")
    imu, epoch, counts = imu_table(dec.imu_samples, to_utc, notes, _device_baud(dec, "imu"))
    epoch_utc = utc_of(epoch)
    from hardware.records import GnssFix

    any_fix = any(isinstance(r, GnssFix) for r in dec.gnss_records)
    first_fix = next((r for r in dec.gnss_records if isinstance(r, GnssFix) and usable_fix(r)), None)
    if options.origin_deg is not None:
        lat, lon, h = options.origin_deg
        origin = (math.radians(lat), math.radians(lon), float(h))
        origin_src = "--origin"
    elif first_fix is not None:
        origin = (first_fix.lat_rad, first_fix.lon_rad, fix_height_m(first_fix))
        origin_src = "first GNSS fix with a finite latitude, longitude and height"
    else:
        origin = None
        origin_src = "none"
    fixes, fcounts = fix_table(dec.gnss_records, to_utc, epoch, origin, notes) if origin else (FixTable.empty(),
                                                                                               {"gnss_fixes": 0})
    alpha, bsum, elements = (beacon_table(folder, out_dir, to_utc, dec.time_map.valid, epoch, origin, elements,
                                          notes, progress) if origin else
                             (AlphaTable.empty(), {"reason_empty": "no position to predict satellites from "
                                                   "(no GNSS fix; give --origin)"}
                              | _default_carrier("no beacon processing"), elements))
    if bsum["carrier_source"].startswith("default") and (folder / "sdr.cu8").exists():
        notes.append(f"beacons: carrier f_c = {bsum['carrier_source']}")
    profile = filter_profile(counts["imu_period_s"], quantized=True)
    if origin is None:
        # nothing can run: keep a valid (empty) result with the reasons
        origin = (0.0, 0.0, 0.0)
    inputs = assemble(epoch_utc, origin, imu, fixes, alpha, elements, options, profile, nav, notes,
                      carrier_hz=bsum["carrier_hz"])
    inputs.counts |= counts | fcounts | {"gnss_decoder": dec.gnss_summary, "imu_decoder": dec.imu_summary}
    inputs.beacons = bsum
    inputs.init |= {"origin": origin_src, "origin_deg": [math.degrees(origin[0]), math.degrees(origin[1]), origin[2]],
                    "time_axis": time_src, "epoch_utc": epoch_utc}
    if origin_src == "--origin":
        inputs.init["origin_given"] = True
    for mode in options.modes:
        if "fix" in MODE_USES[mode] and fixes.t.size == 0:
            inputs.skipped[mode] = ("no GNSS fix in gnss.raw" if not any_fix else
                                    "no GNSS fix with a finite latitude, longitude and height in gnss.raw"
                                    if first_fix is None else "no GNSS fix inside the IMU time span")
        elif origin_src == "none":
            inputs.skipped[mode] = "no initial position: no GNSS fix (give --origin LAT LON H)"
    for mode, reason in skip_reasons(inputs, options.modes).items():
        inputs.skipped.setdefault(mode, reason)
    return inputs


def replay_session(folder: str | Path, out_dir: str | Path, options: ReplayOptions | None = None, elements=None,
                   progress=None, nav: navfuncs.NavFunctions | None = None,
                   inputs: SessionInputs | None = None) -> dict:
    """Decode, run the modes, score against truth.csv or the fixes, write the outputs; returns metrics.

    inputs: the session already decoded by `decode_inputs` with the same options and
    out_dir (its beacon outputs are there), so a caller that needs them decodes only once."""
    options = check_options(options or ReplayOptions())
    folder, out_dir = Path(folder), Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    nav = nav or navfuncs.NavFunctions()
    if inputs is None:
        inputs = decode_inputs(folder, options, elements, out_dir, nav, progress)
    else:
        nav.params = inputs.params
    runs = run_modes(inputs, options.modes, options.gate_nis, nav)
    truth = folder / "truth.csv"
    ref = None
    if options.use_truth and truth.is_file():
        ref = truth_reference(truth, inputs.epoch_utc, inputs.origin, nav)
    elif inputs.fixes.t.size:
        ref = fix_reference(inputs.fixes)
        inputs.notes.append("reference = the GNSS fixes: GPS+IMU is compared with its own input (optimistic); "
                            "velocity and attitude have no reference")
    scored = evaluate(inputs, runs, ref, nav)
    metrics = {
        "session": str(folder), "reference": ref.kind if ref else None,
        "modes": mode_metrics(runs, scored, nav),
        "skipped_modes": inputs.skipped, "counts": inputs.counts, "initialization": inputs.init,
        "beacons": inputs.beacons, "notes": inputs.notes,
        "carrier_hz": inputs.carrier_hz, "carrier_source": inputs.beacons.get("carrier_source"),
        "alpha_sigma_floor_hz_s": options.alpha_sigma_floor_hz_s, "gate_nis": options.gate_nis,
    }
    write_outputs(out_dir, inputs, scored, metrics, ref, nav)
    return metrics


def write_outputs(out_dir: Path, inputs: SessionInputs, scored: dict, metrics: dict, ref: Reference | None,
                  nav: navfuncs.NavFunctions) -> None:
    """metrics.json, rmse_vs_time.csv, trajectory.csv, rmse_vs_time.png, trajectories.png."""
    write_json(out_dir / "metrics.json", metrics)
    rows, traj = [], []
    for mode, s in scored.items():
        e = s["err"]
        euler = nav.euler_from_quat(s["x"][:, 6:10]) if s["x"].size else np.zeros((0, 3))
        for i, t in enumerate(s["t"]):
            rows.append([t, mode, _norm(e[i, 0:3]), _norm(e[i, 0:2]), abs(e[i, 2]), _norm(e[i, 3:6]),
                         math.degrees(_norm(e[i, 6:9]))])
            traj.append([t, mode, *s["x"][i, 0:6], *np.degrees(euler[i]), *s["sigma"][i, 0:6]])
    write_csv(out_dir / "rmse_vs_time.csv", ["t_s", "mode", "position_error_m", "horizontal_error_m",
                                             "vertical_error_m", "velocity_error_mps", "attitude_error_deg"], rows)
    write_csv(out_dir / "trajectory.csv", ["t_s", "mode", "p_e_m", "p_n_m", "p_u_m", "v_e_mps", "v_n_mps", "v_u_mps",
                                           "roll_deg", "pitch_deg", "yaw_deg", "sigma_p_e_m", "sigma_p_n_m",
                                           "sigma_p_u_m", "sigma_v_e_mps", "sigma_v_n_mps", "sigma_v_u_mps"], traj)
    (out_dir / "columns.txt").write_text(
        "rmse_vs_time.csv: t_s [s since the first IMU sample, UTC in metrics.json initialization.epoch_utc], mode, "
        "position/horizontal/vertical error [m], velocity error [m/s], attitude error [deg] = norms of "
        "estimate [-] reference (ENU at the origin; attitude as body rotation vector); NaN where the reference "
        "has no such quantity.\ntrajectory.csv: the estimates at the same times, ENU (m, m/s), Euler roll/pitch/yaw "
        "(deg, yaw from East towards North) and 1-sigma from the filter's covariance.\n")
    plot_rmse_vs_time(out_dir / "rmse_vs_time.png", scored, metrics)
    plot_trajectories(out_dir / "trajectories.png", scored, ref, inputs)


def _norm(v: np.ndarray) -> float:
    return float(np.sqrt(np.sum(v**2)))


def plot_rmse_vs_time(path: Path, scored: dict, metrics: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(9, 8.5), sharex=True)
    blocks = (("position", slice(0, 3), 1.0, "m"), ("velocity", slice(3, 6), 1.0, "m/s"),
              ("attitude", slice(6, 9), 180 / math.pi, "deg"))
    for ax, (name, sl, scale, unit) in zip(axes, blocks):
        for mode, s in scored.items():
            e = np.sqrt(np.sum(s["err"][:, sl] ** 2, axis=1)) * scale
            if np.any(np.isfinite(e)):
                ax.plot(s["t"], e, label=mode)
        ax.set_ylabel(f"{name} error ({unit})")
        ax.grid(True, alpha=0.3)
    if axes[0].get_legend_handles_labels()[0]:
        axes[0].legend(fontsize=8)
    axes[-1].set_xlabel("time since the first IMU sample (s)")
    ref = metrics.get("reference") or "none"
    fig.suptitle(f"Replay of {Path(metrics['session']).name}: error vs time (reference: {ref})", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_trajectories(path: Path, scored: dict, ref: Reference | None, inputs: SessionInputs) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(13, 5.5))
    ax2 = fig.add_subplot(1, 2, 1)
    ax3 = fig.add_subplot(1, 2, 2, projection="3d")
    if ref is not None:
        style = dict(color="k", lw=2.0, label=f"reference ({ref.kind})")
        if ref.q_nb is None:
            ax2.scatter(ref.p_enu[:, 0], ref.p_enu[:, 1], s=6, color="0.5", label="GNSS fixes")
            ax3.scatter(ref.p_enu[:, 0], ref.p_enu[:, 1], ref.p_enu[:, 2], s=4, color="0.5")
        else:
            sel = (ref.t >= inputs.imu.t[0] - 0.2) & (ref.t <= inputs.imu.t[-1] + 0.2)
            ax2.plot(ref.p_enu[sel, 0], ref.p_enu[sel, 1], "*-", ms=12, zorder=5, **style)
            ax3.plot(ref.p_enu[sel, 0], ref.p_enu[sel, 1], ref.p_enu[sel, 2], "*-", ms=10, color="k", zorder=5)
    if inputs.fixes.t.size and (ref is None or ref.q_nb is not None):
        ax2.scatter(inputs.fixes.enu[:, 0], inputs.fixes.enu[:, 1], s=5, color="0.7", label="GNSS fixes")
    for mode, s in scored.items():
        p = s["x"][:, 0:3]
        ax2.plot(p[:, 0], p[:, 1], lw=1.2, label=mode)
        ax3.plot(p[:, 0], p[:, 1], p[:, 2], lw=1.2)
    ax2.set_xlabel("East (m)")
    ax2.set_ylabel("North (m)")
    ax2.axis("equal")
    ax2.grid(True, alpha=0.3)
    ax2.legend(fontsize=8)
    ax3.set_xlabel("East (m)")
    ax3.set_ylabel("North (m)")
    ax3.set_zlabel("Up (m)")
    fig.suptitle("2D and 3D trajectories (ENU at the origin)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
