"""Synthetic `leonav record` sessions: the paper's rig simulated down to the bytes.

`write_synthetic_session(folder, cfg)` writes a session folder in exactly the formats
`leonav record` writes (hardware/README.md), so `decode_session` and `leonav replay` read
it unchanged, plus `truth.csv` and `synthetic.json`, which a real recorder cannot write.

What is simulated (times in s since `cfg.epoch_utc`, the truth's t = 0):
- Truth: the simulator's static scenario at the site (`simulate._truth`: the intended
  motion turned into IMU increments by inverting the *generated* mechanization), so the
  truth is exactly the filter model's own trajectory. Static because the beacon capture
  synthesizer (`beacons.synth`) predicts the tones for a receiver at rest at the site.
- IMU (WitMotion WT901C-TTL, `cfg.imu_rate_hz`, default 10 Hz as in the paper): the true
  increments plus the WT901 profile's biases (random walks) and white noise, drawn by
  `simulate.bias_walks` and `simulate.measured_increments` as the Monte Carlo trials do. Sample k reports the mean rate and specific force
  over (t_k - dt, t_k] in 0x51/0x52/0x53 packets (int16 counts: 4.79e-3 m/s^2,
  0.061 deg/s); the 0x53 angles are the true attitude plus a constant AHRS error
  (`ahrs_sigma_*`) plus 0.02 deg white noise.
- GNSS (u-blox NEO-M10 NMEA, `cfg.gnss_rate_hz`): per epoch RMC, GGA and GST; positions are
  truth plus white noise (`fix_sigma_en_m` per horizontal axis, `fix_sigma_u_m` up), GST
  reports those sigmas, RMC the speed/course of the true velocity plus noise. Degraded
  starts for tests: no GNSS output before `gnss_start_s`, and GGA sentences with an empty
  altitude field before `gga_no_altitude_s` (a receiver without a height yet).
- Serial timing: each epoch's burst leaves the device `*_latency_s` after its epoch and
  is serialized at the port's baud (10 bits per byte); the host reads whatever has
  arrived at read times spaced by ~`host_read_s` (exponential, plus 0.5 ms), and stamps
  each chunk with its monotonic clock (`mono_at_epoch_s + t`). The chunk index files,
  the live CSVs (with the running time map, as the recorder fills them) and
  session.json follow from those stamps.
- SDR: `beacons.synth` writes `sdr.cu8` with `cfg.n_satellites` Starlink tones at the
  carrier `carrier_hz` (C/N0 `cn0_dbhz`, LNB LO `lnb_lo_hz` with error `lo_offset_hz`)
  starting at t = `sdr_start_s`, the SDR tuned to carrier - LNB LO; its SigMF
  metadata is written by `hardware.sdr.capture.sigmf_metadata` like the recorder's, with
  `core:datetime` from the host's wall clock (off by `host_clock_error_s`) and the
  monotonic stamps of the first and last sample.
"""
from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import math
import shutil
import warnings
from pathlib import Path
from typing import Callable

import numpy as np

from hardware.clock import utc_unix
from hardware.gnss import nmea_write
from hardware.gnss.reader import GnssDecoder
from hardware.imu import witmotion_encode as wenc
from hardware.imu.witmotion import SampleGrouper, WitMotionParser
from hardware.records import GnssTimeTag
from hardware.sdr import capture as sdr_capture
from hardware.session import (GNSS_FIX_COLUMNS, GNSS_RAW_COLUMNS, IMU_COLUMNS, SESSION_VERSION, CsvSink,
                              RawLog, RunningTimeMap, gnss_rows, imu_row)
from leonav_runtime import geometry, navfuncs, simulate
from leonav_runtime.errors import UserInputError
from leonav_runtime.output import write_csv, write_json
from leonav_runtime.gen.constants import STARLINK_BEACON_HZ

ROCHESTER = (43.0848638, -77.6786127, 170.0)   # the paper's site: deg, deg, m (ellipsoidal)
PAPER_EPOCH = _dt.datetime(2026, 2, 23, 12, 0, tzinfo=_dt.timezone.utc)
BITS_PER_BYTE = 10                             # UART 8N1
RECORDER_CLOCK_TEXT = "time.monotonic() of the recording host, stamped when a chunk is read"
TRUTH_COLUMNS = ["utc_unix_s", "t_s", "lat_deg", "lon_deg", "h_m", "p_e_m", "p_n_m", "p_u_m",
                 "v_e_mps", "v_n_mps", "v_u_mps", "roll_rad", "pitch_rad", "yaw_rad",
                 "b_a_x_mps2", "b_a_y_mps2", "b_a_z_mps2", "b_g_x_radps", "b_g_y_radps", "b_g_z_radps"]


@dataclasses.dataclass
class SynthSessionConfig:
    """Settings of a synthetic session (SI units; degrees only where the name says so)."""

    seconds: float = 20.0
    seed: int = 0
    epoch_utc: _dt.datetime = PAPER_EPOCH
    lat_deg: float = ROCHESTER[0]
    lon_deg: float = ROCHESTER[1]
    alt_m: float = ROCHESTER[2]
    attitude_deg: tuple[float, float, float] = (0.0, 0.0, 90.0)   # roll, pitch, yaw (from East to North)
    imu_rate_hz: float = 10.0
    gnss_rate_hz: float = 10.0
    fix_sigma_en_m: float = 1.5            # per horizontal axis (u-blox class, ~2.1 m horizontal RMS)
    fix_sigma_u_m: float = 3.0
    speed_sigma_mps: float = 0.05          # RMC speed noise per horizontal axis
    geoid_sep_m: float = -34.5             # EGM96 geoid height near Rochester NY (approx.)
    ahrs_sigma_rp_deg: float = 0.1         # constant error of the sensor's roll/pitch output
    ahrs_sigma_yaw_deg: float = 1.0        # constant error of its yaw output
    gnss_baud: int = 38400
    imu_baud: int = 9600
    gnss_latency_s: float = 0.035          # receiver output latency after the epoch
    gnss_start_s: float = 0.0              # no GNSS output before this time (receiver still acquiring)
    gga_no_altitude_s: float = 0.0         # GGA altitude field empty before this time (no height yet)
    imu_latency_s: float = 0.002
    host_read_s: float = 0.004             # mean spacing of the host's serial reads
    host_clock_error_s: float = 0.3        # host wall clock minus UTC (no NTP on the Pi)
    mono_at_epoch_s: float = 8_642.125     # host monotonic clock at the truth's t = 0
    sdr: bool = True
    sdr_rate_hz: float = 400e3
    sdr_start_s: float = 0.05              # first IQ sample at this truth time
    carrier_hz: float = STARLINK_BEACON_HZ # beacon tone RF frequency, also the recorder's RF centre
    lnb_lo_hz: float = sdr_capture.DEFAULT_LNB_LO_HZ
    n_satellites: int = 5
    cn0_dbhz: float = 40.0
    lo_offset_hz: float = 20e3


@dataclasses.dataclass
class SyntheticSession:
    """What went into a synthetic session, before any byte formatting (floats, exact times)."""

    folder: Path
    cfg: SynthSessionConfig
    params: np.ndarray
    t_imu: np.ndarray          # (n+1,) truth sample times, s
    x_true: np.ndarray         # (n+1, NX) truth incl. biases (clock and LO states zero)
    u_meas: np.ndarray         # (n, 6) noisy increments of interval k = (t_k, t_k+1], before quantization
    ahrs_rpy: np.ndarray       # (n, 3) angles the sensor reports at samples 1..n, rad
    fix_t: np.ndarray          # (m,) GNSS epochs written (from cfg.gnss_start_s on), s
    fix_enu: np.ndarray        # (m, 3) noisy fixes in the truth's ENU frame, m (altitude not sent before
                               # cfg.gga_no_altitude_s)
    fix_vel_en: np.ndarray     # (m, 2) noisy RMC velocity (E, N), m/s
    sdr_info: dict             # capture truth (satellites, LO) or {} without SDR
    elements: object = None    # the Starlink ElementSet used for the tones

    @property
    def origin(self) -> tuple[float, float, float]:
        return math.radians(self.cfg.lat_deg), math.radians(self.cfg.lon_deg), self.cfg.alt_m


# ------------------------------------------------------------------ truth and noise


def _scenario(cfg: SynthSessionConfig):
    from leonav_runtime.scenario import scenario_from_dict

    return scenario_from_dict({
        "name": "synthetic-session",
        "site": {"lat_deg": cfg.lat_deg, "lon_deg": cfg.lon_deg, "alt_m": cfg.alt_m},
        "time": {"epoch": cfg.epoch_utc.isoformat().replace("+00:00", "Z"), "duration_s": cfg.seconds},
        "trajectory": {"kind": "static", "attitude_deg": list(cfg.attitude_deg)},
        "imu": {"profile": "wt901", "rate_hz": cfg.imu_rate_hz},
        "gps": {"rate_hz": cfg.gnss_rate_hz},
    }, source="<synthetic session>")


def simulate_sensors(cfg: SynthSessionConfig, nav: navfuncs.NavFunctions | None = None) -> dict:
    """Truth and float sensor values (no bytes yet). Keys as in `SyntheticSession`."""
    from leonav_runtime.gen.profiles import WT901
    from leonav_runtime.params import build_params

    if cfg.imu_rate_hz <= 0 or cfg.gnss_rate_hz <= 0 or cfg.seconds <= 1.0:
        raise UserInputError("synthetic session: expected seconds > 1 and positive IMU/GNSS rates")
    step = cfg.imu_rate_hz / cfg.gnss_rate_hz
    if abs(step - round(step)) > 1e-9:
        raise UserInputError(f"synthetic session: GNSS rate {cfg.gnss_rate_hz} Hz must divide the IMU rate "
                             f"{cfg.imu_rate_hz} Hz")
    scn = _scenario(cfg)
    params = np.array(build_params(scn.lat_rad, scn.lon_rad, scn.alt_m, imu=WT901,
                                   q_blo=simulate.LO_RANDOM_WALK_HZ2_S, f_c_hz=cfg.carrier_hz))
    nav = nav or navfuncs.NavFunctions()
    nav.params = params
    t, x_true, u_true = simulate.truth(scn, params, nav)
    L = nav.layout
    rng = np.random.default_rng(cfg.seed)
    n, dt = u_true.shape[0], 1.0 / cfg.imu_rate_hz
    b_a, b_g = simulate.bias_walks(rng, WT901, n, dt)
    x_true = x_true.copy()
    x_true[:, L.X_B_A:L.X_B_A + 3], x_true[:, L.X_B_G:L.X_B_G + 3] = b_a, b_g
    u = simulate.measured_increments(rng, WT901, u_true, b_a, b_g, dt)

    euler = nav.euler_from_quat(x_true[1:, L.X_Q_NB:L.X_Q_NB + 4])
    ahrs_err = np.radians([cfg.ahrs_sigma_rp_deg, cfg.ahrs_sigma_rp_deg, cfg.ahrs_sigma_yaw_deg])
    ahrs = euler + ahrs_err * rng.standard_normal(3) + np.radians(0.02) * rng.standard_normal((n, 3))

    k_fix = np.arange(int(round(step)), n + 1, int(round(step)))
    p = x_true[k_fix, L.X_P_ENU:L.X_P_ENU + 3]
    v = x_true[k_fix, L.X_V_ENU:L.X_V_ENU + 3]
    sig = np.array([cfg.fix_sigma_en_m, cfg.fix_sigma_en_m, cfg.fix_sigma_u_m])
    fix_enu = p + sig * rng.standard_normal(p.shape)
    fix_vel = v[:, :2] + cfg.speed_sigma_mps * rng.standard_normal((k_fix.size, 2))
    sent = t[k_fix] >= cfg.gnss_start_s - 1e-9      # drawn for every epoch: same noise whatever the start
    return {"params": params, "t_imu": t, "x_true": x_true, "u_meas": u, "ahrs_rpy": ahrs,
            "fix_t": t[k_fix][sent], "fix_enu": fix_enu[sent], "fix_vel_en": fix_vel[sent], "scn": scn}


# ------------------------------------------------------------------ serial bytes and host reads


def serial_chunks(bursts: list[tuple[float, bytes]], baud: int, rng: np.random.Generator,
                  host_read_s: float, t_stop: float) -> list[tuple[bytes, float]]:
    """(chunk, t_read) as a host reading a UART would see them.

    bursts: (time the first byte starts, bytes), in time order. Bytes go out back to back
    at `baud` (a burst waits for the previous one); byte i is complete at start +
    (i+1)*10/baud. The host reads at times spaced by 0.5 ms + Exp(host_read_s) and gets
    every byte complete by then; reads that find nothing return nothing.
    """
    if not bursts:
        return []
    t_byte = BITS_PER_BYTE / baud
    ends, data = [], []
    free = -math.inf
    for t0, payload in bursts:
        start = max(t0, free)
        e = start + t_byte * np.arange(1, len(payload) + 1)
        ends.append(e)
        data.append(payload)
        free = e[-1]
    ends_all = np.concatenate(ends)
    blob = b"".join(data)
    n_reads = int((max(t_stop, ends_all[-1]) - bursts[0][0]) / (0.0005 + host_read_s)) * 2 + 10
    reads = bursts[0][0] + np.cumsum(0.0005 + rng.exponential(host_read_s, n_reads))
    reads = reads[reads <= max(t_stop, ends_all[-1]) + 0.06]
    reads = np.append(reads, ends_all[-1] + 0.001)       # the last bytes are read
    cut = np.searchsorted(ends_all, reads, side="right")
    out, prev = [], 0
    for c, t in zip(cut, reads):
        if c > prev:
            out.append((blob[prev:c], float(t)))
            prev = c
    return out


def _gnss_bursts(cfg: SynthSessionConfig, sim: dict) -> list[tuple[float, bytes]]:
    lat0, lon0, h0 = math.radians(cfg.lat_deg), math.radians(cfg.lon_deg), cfg.alt_m
    r0 = geometry.geodetic_to_ecef(lat0, lon0, h0)
    lat, lon, h = geometry.ecef_to_geodetic(geometry.enu_to_ecef(sim["fix_enu"], r0, lat0, lon0))
    out = []
    for j, t in enumerate(sim["fix_t"]):
        utc = cfg.epoch_utc + _dt.timedelta(seconds=float(t))
        la, lo = math.degrees(lat[j]), math.degrees(lon[j])
        gga = nmea_write.gga(utc, la, lo, float(h[j]) - cfg.geoid_sep_m, cfg.geoid_sep_m, 1, 14, 0.72)
        if t < cfg.gga_no_altitude_s - 1e-9:
            gga = _without_altitude(gga)
        msg = (nmea_write.rmc(utc, la, lo, *sim["fix_vel_en"][j]) + gga
               + nmea_write.gst(utc, cfg.fix_sigma_en_m, cfg.fix_sigma_en_m, cfg.fix_sigma_u_m, 1.8))
        out.append((float(t) + cfg.gnss_latency_s, msg))
    return out


def _without_altitude(gga: bytes) -> bytes:
    """The GGA sentence with its altitude field (the 10th, after the talker+type) emptied."""
    fields = gga.decode("ascii").strip()[1:].split("*")[0].split(",")
    fields[9] = ""
    return nmea_write.sentence(",".join(fields))


def _imu_bursts(cfg: SynthSessionConfig, sim: dict) -> list[tuple[float, bytes]]:
    dt = 1.0 / cfg.imu_rate_hz
    out = []
    for k in range(sim["u_meas"].shape[0]):
        w, f = sim["u_meas"][k, :3] / dt, sim["u_meas"][k, 3:] / dt
        msg = wenc.acc_packet(f, 24.5) + wenc.gyro_packet(w) + wenc.angle_packet(sim["ahrs_rpy"][k])
        out.append((float(sim["t_imu"][k + 1]) + cfg.imu_latency_s, msg))
    return out


# ------------------------------------------------------------------ the session folder


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


def builtin_starlink(epoch_utc: _dt.datetime):
    """The built-in Walker Starlink set generated at the UTC minute nearest to `epoch_utc`
    (`leonav replay` uses the same rule on the capture start, so a synthetic session and its
    replay agree as long as the mapped start is within 30 s of the true one)."""
    from leonav_runtime.orbits import parse_elements_text, starlink_walker_tle

    minute = (epoch_utc.astimezone(_dt.timezone.utc) + _dt.timedelta(seconds=30)).replace(second=0, microsecond=0)
    return parse_elements_text(starlink_walker_tle(minute), "<leonav starlink walker>", constellation="starlink")


def _write_sdr(folder: Path, cfg: SynthSessionConfig, elements, progress) -> dict:
    from leonav_runtime.beacons import synth
    from leonav_runtime.beacons.predict import Site

    settings = sdr_capture.SdrSettings(rf_center_hz=cfg.carrier_hz, lnb_lo_hz=cfg.lnb_lo_hz,
                                       sample_rate_hz=cfg.sdr_rate_hz, gain_db=30.0)
    start = cfg.epoch_utc + _dt.timedelta(seconds=cfg.sdr_start_s)
    duration = cfg.seconds - cfg.sdr_start_s - 0.05
    scfg = synth.SynthConfig(duration_s=duration, sample_rate_hz=cfg.sdr_rate_hz, center_freq_hz=settings.if_hz,
                             lnb_lo_hz=settings.lnb_lo_hz, tone_rf_hz=cfg.carrier_hz, cn0_dbhz=cfg.cn0_dbhz,
                             lo_offset_hz=cfg.lo_offset_hz,
                             n_satellites=cfg.n_satellites, seed=cfg.seed)
    site = Site(math.radians(cfg.lat_deg), math.radians(cfg.lon_deg), cfg.alt_m)
    data = folder / "sdr.cu8"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # stale-element warnings: the replay reports them
        try:
            info, truth = synth.write_synthetic_capture(data, elements, site, start, scfg, "cu8", progress=progress)
        except ValueError as exc:
            raise UserInputError(f"synthetic session SDR: {exc}") from None
    Path(str(data) + ".json").unlink(missing_ok=True)    # the recorder writes SigMF metadata instead
    mono_start = cfg.mono_at_epoch_s + cfg.sdr_start_s
    mono_stop = mono_start + info.n_samples / cfg.sdr_rate_hz
    host_start = start + _dt.timedelta(seconds=cfg.host_clock_error_s)
    meta = sdr_capture.sigmf_metadata(settings, settings.if_hz, host_start, cfg.sdr_rate_hz, data,
                                      extra={"leonav:t_mono_start_s": mono_start, "leonav:t_mono_stop_s": mono_stop,
                                             "leonav:end_reason": "done"})
    (folder / "sdr.sigmf-meta").write_text(json.dumps(meta, indent=2))
    return {"settings": settings, "n_samples": info.n_samples, "t_mono_start_s": mono_start,
            "t_mono_stop_s": mono_stop, "truth": truth}


def _truth_rows(cfg: SynthSessionConfig, sim: dict, nav: navfuncs.NavFunctions) -> list[list]:
    L = nav.layout
    lat0, lon0, h0 = math.radians(cfg.lat_deg), math.radians(cfg.lon_deg), cfg.alt_m
    x = sim["x_true"]
    r = geometry.enu_to_ecef(x[:, 0:3], geometry.geodetic_to_ecef(lat0, lon0, h0), lat0, lon0)
    lat, lon, h = geometry.ecef_to_geodetic(r)
    euler = nav.euler_from_quat(x[:, L.X_Q_NB:L.X_Q_NB + 4])
    t0 = utc_unix(cfg.epoch_utc)
    return [[t0 + t, t, math.degrees(lat[k]), math.degrees(lon[k]), h[k], *x[k, 0:6], *euler[k],
             *x[k, L.X_B_A:L.X_B_A + 3], *x[k, L.X_B_G:L.X_B_G + 3]] for k, t in enumerate(sim["t_imu"])]


def write_synthetic_session(folder: str | Path, cfg: SynthSessionConfig | None = None, elements=None,
                            overwrite: bool = False, progress: Callable[[int], None] | None = None,
                            nav: navfuncs.NavFunctions | None = None) -> SyntheticSession:
    """Write a synthetic session (see the module doc) into `folder`.

    elements: Starlink ElementSet for the tones (default: `builtin_starlink(cfg.epoch_utc)`).
    progress(n): called with IQ samples written.
    """
    cfg = cfg or SynthSessionConfig()
    folder = Path(folder)
    if folder.exists() and any(folder.iterdir()):
        if not overwrite:
            raise UserInputError(f"{folder}: folder exists and is not empty (give an empty or new folder)")
        shutil.rmtree(folder)
    folder.mkdir(parents=True, exist_ok=True)
    nav = nav or navfuncs.NavFunctions()
    sim = simulate_sensors(cfg, nav)
    rng = np.random.default_rng([cfg.seed, 7])
    mono0 = cfg.mono_at_epoch_s
    t_start, t_stop = -0.3, cfg.seconds + 0.2
    gnss_chunks = serial_chunks(_gnss_bursts(cfg, sim), cfg.gnss_baud, rng, cfg.host_read_s, t_stop)
    imu_chunks = serial_chunks(_imu_bursts(cfg, sim), cfg.imu_baud, rng, cfg.host_read_s, t_stop)
    _write_raw(folder, "gnss", gnss_chunks, mono0)
    _write_raw(folder, "imu", imu_chunks, mono0)
    gnss_sum, imu_sum, tmap = _live_csvs(folder, gnss_chunks, imu_chunks, mono0)

    if elements is None and cfg.sdr:
        elements = builtin_starlink(cfg.epoch_utc)
    sdr = _write_sdr(folder, cfg, elements, progress) if cfg.sdr else {}

    host = lambda t: cfg.epoch_utc + _dt.timedelta(seconds=t + cfg.host_clock_error_s)  # noqa: E731
    devices = [
        {"kind": "gnss", "port": "synthetic:gnss", "baud": cfg.gnss_baud, "error": ""} | gnss_sum,
        {"kind": "imu", "port": "synthetic:imu", "baud": cfg.imu_baud, "error": ""} | imu_sum,
    ]
    info = {"leonav_session_version": SESSION_VERSION, "status": "complete",
            "start_utc": host(t_start).isoformat(), "t_mono_start_s": mono0 + t_start,
            "clock": RECORDER_CLOCK_TEXT, "devices": devices}
    if sdr:
        s = sdr["settings"]
        devices.append({"kind": "sdr", "port": "0", "baud": None, "end_reason": "done", "error": "",
                        "n_samples": sdr["n_samples"], "if_hz": s.if_hz, "sample_rate_hz": s.sample_rate_hz,
                        "t_mono_start_s": sdr["t_mono_start_s"], "t_mono_stop_s": sdr["t_mono_stop_s"]})
        info["sdr_settings"] = {"rf_center_hz": s.rf_center_hz, "lnb_lo_hz": s.lnb_lo_hz, "if_hz": s.if_hz,
                                "sample_rate_hz": s.sample_rate_hz, "gain_db": s.gain_db, "ppm": s.ppm}
    info |= {"stop_utc": host(t_stop).isoformat(), "t_mono_stop_s": mono0 + t_stop,
             "time_map": tmap.final().as_dict()}
    write_json(folder / "session.json", info)

    write_csv(folder / "truth.csv", TRUTH_COLUMNS, _truth_rows(cfg, sim, nav))
    sdr_truth = sdr["truth"].describe() if sdr else {}
    write_json(folder / "synthetic.json", {
        "note": "synthetic session written by leonav_runtime.session_synth; truth.csv and this file are not "
                "written by `leonav record`",
        "config": dataclasses.asdict(cfg), "sdr_truth": sdr_truth,
        "element_source": "built-in Walker constellation at the nearest UTC minute" if elements is not None
        and getattr(elements, "names", [""])[0].startswith("STARLINK-W") else "given element sets",
    })
    return SyntheticSession(folder, cfg, sim["params"], sim["t_imu"], sim["x_true"], sim["u_meas"], sim["ahrs_rpy"],
                            sim["fix_t"], sim["fix_enu"], sim["fix_vel_en"], sdr_truth, elements)


# ------------------------------------------------------------------ the same run without the bytes


def direct_inputs(synth: SyntheticSession, replayed, options=None, nav: navfuncs.NavFunctions | None = None):
    """The replay's inputs rebuilt from the floats that went into the session (no bytes).

    Same truth, same noise draws, same initialization rules (`replay.assemble`: initial
    fix, averaged specific force and its noise in the Doppler-rate R, prior), same carrier
    and same Doppler-rate values (the beacon pipeline's output of the replay, i.e. the same
    measurement errors), but: exact sample and fix times (no stamps, no time map),
    unquantized IMU values (so the filter's IMU noise is the plain WT901 profile), unrounded
    fixes and angles, and the Doppler-rate epochs at their true times. Fixes the session
    sent without an altitude are left out, as the replay does. The RMSE difference between
    the two runs is what the byte formats and time tagging cost.
    """
    from leonav_runtime import replay

    options = options or replay.ReplayOptions()
    nav = nav or navfuncs.NavFunctions()
    cfg = synth.cfg
    dt = 1.0 / cfg.imu_rate_hz
    lat0, lon0, h0 = synth.origin
    r_site = geometry.geodetic_to_ecef(lat0, lon0, h0)
    sent = synth.fix_t >= cfg.gga_no_altitude_s - 1e-9
    if not np.any(sent):
        raise UserInputError(f"{synth.folder}: no GNSS fix with an altitude: nothing to compare")
    r_fix = geometry.enu_to_ecef(synth.fix_enu[sent], r_site, lat0, lon0)
    lat, lon, h = geometry.ecef_to_geodetic(r_fix[0])
    origin = (float(lat), float(lon), float(h))
    enu = geometry.ecef_to_enu(r_fix, geometry.geodetic_to_ecef(*origin), origin[0], origin[1])
    n = synth.u_meas.shape[0]
    imu = replay.ImuTable(synth.t_imu[1:], np.full(n, dt), synth.u_meas[:, :3] / dt, synth.u_meas[:, 3:] / dt,
                          synth.ahrs_rpy)
    sig = np.tile([cfg.fix_sigma_en_m, cfg.fix_sigma_en_m, cfg.fix_sigma_u_m], (enu.shape[0], 1))
    fixes = replay.FixTable(synth.fix_t[sent], enu, sig, synth.fix_vel_en[sent])
    a = replayed.alpha
    alpha = replay.AlphaTable(a.t, a.norad, a.sat_index, a.z, a.sigma)
    if a.t.size:
        start = replayed.beacons["capture_start_utc"].timestamp()
        alpha.t = cfg.sdr_start_s + (a.t + replayed.epoch_utc.timestamp() - start)   # capture seconds -> truth axis
    inputs = replay.assemble(cfg.epoch_utc, origin, imu, fixes, alpha, synth.elements, options,
                             replay.filter_profile(dt, quantized=False), nav, carrier_hz=replayed.carrier_hz)
    inputs.skipped = dict(replayed.skipped)
    return inputs


def compare_replay_direct(synth: SyntheticSession, out_dir: str | Path, options=None, elements=None,
                          nav: navfuncs.NavFunctions | None = None) -> dict:
    """Replay the session (outputs in out_dir) and run the direct simulation; RMSE of both per mode.

    The session is decoded (and its capture processed) once; both runs use that decoding."""
    from leonav_runtime import replay

    options = options or replay.ReplayOptions(gnss_latency_s=synth.cfg.gnss_latency_s)
    nav = nav or navfuncs.NavFunctions()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    replayed = replay.decode_inputs(synth.folder, options, elements or synth.elements, out_dir, nav)
    metrics = replay.replay_session(synth.folder, out_dir, options, nav=nav, inputs=replayed)
    direct = direct_inputs(synth, replayed, options, nav)
    runs = replay.run_modes(direct, options.modes, options.gate_nis, nav)
    ref = replay.truth_reference(synth.folder / "truth.csv", direct.epoch_utc, direct.origin, nav)
    direct_metrics = replay.mode_metrics(runs, replay.evaluate(direct, runs, ref, nav), nav)
    keys = ("rmse_position_m", "rmse_velocity_mps", "rmse_attitude_deg")
    table = {mode: {k: {"replay": metrics["modes"][mode][k], "direct": direct_metrics[mode][k]} for k in keys}
             for mode in metrics["modes"] if mode in direct_metrics}
    write_json(out_dir / "replay_vs_direct.json", {"note": direct_inputs.__doc__.strip(), "rmse": table,
                                                  "direct": direct_metrics})
    return {"replay": metrics, "direct": direct_metrics, "table": table}
