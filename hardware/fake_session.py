"""Write a session folder from sensor values, in exactly the formats `leonav record` writes.

The caller (`leonav_runtime.simulation.session_synth`) simulates what the devices *report* (floats:
GNSS epochs, IMU samples, an IQ capture file); this module turns them into what a
recording host would have stored:

- bytes: u-blox NMEA RMC + GGA + GST per GNSS epoch (`gnss.nmea_write`), WitMotion
  0x51/0x52/0x53 packets per IMU sample (`imu.witmotion_encode`, int16 quantization);
- serial timing: each burst leaves the device `*_latency_s` after its epoch/sample and is
  serialized at the port's baud (`uart.serialization_s`); the host reads whatever has
  arrived at random read times (`fakes.serial_chunks`) and stamps each chunk with its
  monotonic clock `mono_at_epoch_s + t`;
- files: gnss.raw / imu.raw with their chunk indexes, the live CSVs decoded in arrival
  order with the running time map (as the recorder's threads fill them), the capture's
  SigMF metadata (`sdr.capture.sigmf_metadata`, `core:datetime` from the host's wall
  clock, off by `host_clock_error_s`) and session.json.

Times are s since `epoch_utc` (the truth's t = 0) unless a name says `mono`.
"""
from __future__ import annotations

import datetime as _dt
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from leonav.hardware.fakes import serial_chunks
from leonav.hardware.gnss import nmea_write
from leonav.hardware.gnss.reader import GnssDecoder
from leonav.hardware.imu import witmotion_encode as wenc
from leonav.hardware.imu.witmotion import SampleGrouper, WitMotionParser
from leonav.hardware.jsonfile import write_json
from leonav.hardware.records import GnssTimeTag
from leonav.hardware.sdr import capture as sdr_capture
from leonav.hardware.session_files import (GNSS_FIX_COLUMNS, GNSS_RAW_COLUMNS, IMU_COLUMNS, CsvSink, RawLog,
                                    RunningTimeMap, gnss_rows, imu_row, session_json)

IMU_TEMPERATURE_C = 24.5
SESSION_START_S = -0.3          # the recorder starts before the truth's t = 0 ...
SESSION_STOP_AFTER_S = 0.2      # ... and stops after its end


@dataclass
class GnssOutput:
    """What the receiver reports per epoch: t_s (m,) s; lat_rad, lon_rad (m,) WGS84;
    height_m (m,) ellipsoidal; vel_en_mps (m, 2) East/North (RMC speed and course);
    GST 1-sigma sigma_en_m (per horizontal axis) and sigma_u_m; geoid_sep_m (GGA height
    = height_m - geoid_sep_m above mean sea level); GGA altitude field empty before
    `no_altitude_before_s` (a receiver without a height yet)."""

    t_s: np.ndarray
    lat_rad: np.ndarray
    lon_rad: np.ndarray
    height_m: np.ndarray
    vel_en_mps: np.ndarray
    sigma_en_m: float
    sigma_u_m: float
    geoid_sep_m: float
    no_altitude_before_s: float = 0.0


@dataclass
class ImuOutput:
    """What the WitMotion reports per sample: t_s (n,) sample times, s; w_b_radps (n, 3) and
    f_b_mps2 (n, 3), body FLU (the mean rate and specific force over the interval ending at
    the sample); rpy_rad (n, 3) its own roll/pitch/yaw output."""

    t_s: np.ndarray
    w_b_radps: np.ndarray
    f_b_mps2: np.ndarray
    rpy_rad: np.ndarray


@dataclass
class HostTiming:
    """Serial ports and the recording host: bauds, device output latencies (s after the
    epoch/sample), mean host read spacing (s), host monotonic clock at t = 0 (s), host wall
    clock minus UTC (s)."""

    gnss_baud: int = 38400
    imu_baud: int = 9600
    gnss_latency_s: float = 0.035
    imu_latency_s: float = 0.002
    host_read_s: float = 0.004
    mono_at_epoch_s: float = 8_642.125
    host_clock_error_s: float = 0.3


@dataclass
class SdrOutput:
    """An IQ capture already written to `<folder>/sdr.cu8`: its settings, sample count and
    the time of its first sample (s)."""

    settings: sdr_capture.SdrSettings
    n_samples: int
    start_s: float


def gnss_bursts(epoch_utc: _dt.datetime, gnss: GnssOutput, latency_s: float) -> list[tuple[float, bytes]]:
    """(time the first byte leaves, RMC + GGA + GST bytes) per epoch."""
    out = []
    for j, t in enumerate(gnss.t_s):
        utc = epoch_utc + _dt.timedelta(seconds=float(t))
        la, lo = math.degrees(gnss.lat_rad[j]), math.degrees(gnss.lon_rad[j])
        gga = nmea_write.gga(utc, la, lo, float(gnss.height_m[j]) - gnss.geoid_sep_m, gnss.geoid_sep_m, 1, 14, 0.72)
        if t < gnss.no_altitude_before_s - 1e-9:
            gga = without_altitude(gga)
        msg = (nmea_write.rmc(utc, la, lo, *gnss.vel_en_mps[j]) + gga
               + nmea_write.gst(utc, gnss.sigma_en_m, gnss.sigma_en_m, gnss.sigma_u_m, 1.8))
        out.append((float(t) + latency_s, msg))
    return out


def without_altitude(gga: bytes) -> bytes:
    """The GGA sentence with its altitude field (the 10th, after the talker+type) emptied."""
    fields = gga.decode("ascii").strip()[1:].split("*")[0].split(",")
    fields[9] = ""
    return nmea_write.sentence(",".join(fields))


def imu_bursts(imu: ImuOutput, latency_s: float) -> list[tuple[float, bytes]]:
    """(time the first byte leaves, 0x51 + 0x52 + 0x53 packets) per sample."""
    return [(float(imu.t_s[k]) + latency_s, wenc.acc_packet(imu.f_b_mps2[k], IMU_TEMPERATURE_C)
             + wenc.gyro_packet(imu.w_b_radps[k]) + wenc.angle_packet(imu.rpy_rad[k]))
            for k in range(imu.t_s.size)]


def _write_raw(folder: Path, name: str, chunks: list[tuple[bytes, float]], mono0: float) -> None:
    log = RawLog(folder, name)
    for chunk, t in chunks:
        log.write(chunk, mono0 + t)
    log.close()


def _live_csvs(folder: Path, gnss_chunks, imu_chunks, mono0: float) -> tuple[dict, dict, RunningTimeMap]:
    """Decode the chunks in arrival order as the recorder's threads do and write the live CSVs
    (running time map). Returns the per-device summaries and the map."""
    events = [(mono0 + t, 0, c) for c, t in gnss_chunks] + [(mono0 + t, 1, c) for c, t in imu_chunks]
    events.sort(key=lambda e: (e[0], e[1]))
    tmap = RunningTimeMap()
    decoder, parser, grouper = GnssDecoder(), WitMotionParser(), SampleGrouper()
    fix_csv = CsvSink(folder / "gnss_fix.csv", GNSS_FIX_COLUMNS)
    imu_csv = CsvSink(folder / "imu.csv", IMU_COLUMNS)
    raw_csv = None
    n_samples = 0
    for t, dev, chunk in events:
        if dev == 0:
            for rec in decoder.decode(chunk, t):
                if isinstance(rec, GnssTimeTag):
                    tmap.add(rec)
                name, rows = gnss_rows(rec, tmap.utc)
                if name == "gnss_raw" and raw_csv is None:
                    raw_csv = CsvSink(folder / "gnss_raw.csv", GNSS_RAW_COLUMNS)
                for row in rows:
                    (fix_csv if name == "gnss_fix" else raw_csv).write(row)
        else:
            for packet in parser.feed(chunk, t):
                for s in grouper.push(packet):
                    imu_csv.write(imu_row(s, tmap.utc))
                    n_samples += 1
    decoder.close()
    parser.close()
    for s in grouper.flush():
        imu_csv.write(imu_row(s, tmap.utc))
        n_samples += 1
    for sink in (fix_csv, imu_csv, raw_csv):
        if sink:
            sink.close()
    rejected = dict(parser.rejected)
    if grouper.incomplete:
        rejected["incomplete_samples"] = grouper.incomplete
    gnss = decoder.summary() | {"bytes_read": sum(len(c) for c, _ in gnss_chunks), "end_reason": "stopped"}
    gnss |= {"acks": [], "csv_rows": {"gnss_fix.csv": fix_csv.rows, "gnss_raw.csv": raw_csv.rows if raw_csv else 0}}
    imu = {"accepted": dict(parser.counts) | {"samples": n_samples}, "rejected": dict(sorted(rejected.items())),
           "bytes_read": sum(len(c) for c, _ in imu_chunks), "end_reason": "stopped",
           "csv_rows": {"imu.csv": imu_csv.rows}}
    return gnss, imu, tmap


def write_capture_metadata(folder: Path, epoch_utc: _dt.datetime, timing: HostTiming, sdr: SdrOutput) -> dict:
    """sdr.sigmf-meta of the capture in `folder`, as the recorder writes it; returns its
    session.json device entry."""
    s = sdr.settings
    mono_start = timing.mono_at_epoch_s + sdr.start_s
    mono_stop = mono_start + sdr.n_samples / s.sample_rate_hz
    host_start = epoch_utc + _dt.timedelta(seconds=sdr.start_s) + _dt.timedelta(seconds=timing.host_clock_error_s)
    meta = sdr_capture.sigmf_metadata(s, s.if_hz, host_start, s.sample_rate_hz, folder / "sdr.cu8",
                                      extra={"leonav:t_mono_start_s": mono_start, "leonav:t_mono_stop_s": mono_stop,
                                             "leonav:end_reason": "done"})
    (folder / "sdr.sigmf-meta").write_text(json.dumps(meta, indent=2))
    return {"kind": "sdr", "port": "0", "baud": None, "end_reason": "done", "error": "",
            "n_samples": sdr.n_samples, "if_hz": s.if_hz, "sample_rate_hz": s.sample_rate_hz,
            "t_mono_start_s": mono_start, "t_mono_stop_s": mono_stop}


def write_fake_session(folder: Path, epoch_utc: _dt.datetime, duration_s: float, gnss: GnssOutput,
                       imu: ImuOutput, timing: HostTiming, rng: np.random.Generator,
                       sdr: SdrOutput | None = None, extra_gnss: list[tuple[float, bytes]] = ()) -> dict:
    """Raw logs, chunk indexes, live CSVs, SigMF metadata (with `sdr`) and session.json of a
    session of `duration_s` in the existing folder `folder` (see the module doc). `rng` draws
    the host's read times (GNSS first, then IMU). extra_gnss: (epoch time s, bytes) the
    receiver sends besides the NMEA of `gnss` (e.g. UBX RXM-RAWX / RXM-SFRBX frames), leaving
    it `gnss_latency_s` after the time. Returns session.json's content."""
    mono0 = timing.mono_at_epoch_s
    t_start, t_stop = SESSION_START_S, duration_s + SESSION_STOP_AFTER_S
    bursts = gnss_bursts(epoch_utc, gnss, timing.gnss_latency_s)
    if len(extra_gnss):
        bursts = sorted(bursts + [(float(t) + timing.gnss_latency_s, b) for t, b in extra_gnss], key=lambda e: e[0])
    gnss_chunks = serial_chunks(bursts, timing.gnss_baud, rng, timing.host_read_s, t_stop)
    imu_chunks = serial_chunks(imu_bursts(imu, timing.imu_latency_s), timing.imu_baud, rng, timing.host_read_s,
                               t_stop)
    _write_raw(folder, "gnss", gnss_chunks, mono0)
    _write_raw(folder, "imu", imu_chunks, mono0)
    gnss_sum, imu_sum, tmap = _live_csvs(folder, gnss_chunks, imu_chunks, mono0)

    def host(t: float) -> str:
        return (epoch_utc + _dt.timedelta(seconds=t + timing.host_clock_error_s)).isoformat()

    devices = [
        {"kind": "gnss", "port": "synthetic:gnss", "baud": timing.gnss_baud, "error": ""} | gnss_sum,
        {"kind": "imu", "port": "synthetic:imu", "baud": timing.imu_baud, "error": ""} | imu_sum,
    ]
    if sdr is not None:
        devices.append(write_capture_metadata(folder, epoch_utc, timing, sdr))
    info = session_json("complete", host(t_start), mono0 + t_start, devices, sdr.settings if sdr else None,
                        (host(t_stop), mono0 + t_stop, tmap.final()))
    write_json(folder / "session.json", info)
    return info
