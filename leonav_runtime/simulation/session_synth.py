"""Synthetic `leonav record` sessions: the paper's rig simulated down to the bytes.

`write_synthetic_session(folder, cfg)` writes a session folder in exactly the formats
`leonav record` writes (hardware/README.md), so `decode_session` and `leonav replay` read
it unchanged, plus `truth.csv` and `synthetic.json`, which a real recorder cannot write.

This module simulates what the sensors *report* (floats); the bytes, the serial timing
and the recorder's files are made by `hardware.fake_session` (NMEA and WitMotion
encoders, UART timing, host read stamps, live CSVs, SigMF metadata, session.json).

What is simulated (times in s since `cfg.epoch_utc`, the truth's t = 0):
- Truth: the simulator's static scenario at the site (`simulate.truth`: the intended
  motion turned into IMU increments by inverting the *generated* mechanization), so the
  truth is exactly the filter model's own trajectory. Static because the beacon capture
  synthesizer (`beacons.synth`) predicts the tones for a receiver at rest at the site.
- IMU (WitMotion WT901C-TTL, `cfg.imu_rate_hz`, default 10 Hz as in the paper): the true
  increments plus the WT901 profile's biases (random walks) and white noise, drawn by
  `simulate.bias_walks` and `simulate.measured_increments` as the Monte Carlo trials do.
  Sample k reports the mean rate and specific force over (t_k - dt, t_k] (the writer
  quantizes them to int16 counts: 4.79e-3 m/s^2, 0.061 deg/s); its angle output is the
  true attitude plus a constant AHRS error (`ahrs_sigma_*`) plus 0.02 deg white noise.
- GNSS (u-blox NEO-M10 NMEA, `cfg.gnss_rate_hz`): per epoch a fix = truth plus white noise
  (`fix_sigma_en_m` per horizontal axis, `fix_sigma_u_m` up), reported with those sigmas
  (GST) and the true velocity plus noise (RMC speed/course). Degraded starts for tests:
  no GNSS output before `gnss_start_s`, and GGA sentences with an empty altitude field
  before `gga_no_altitude_s` (a receiver without a height yet).
- Serial timing (`hardware.fake_session.HostTiming`): bauds, device latencies, host read
  spacing `host_read_s`, host monotonic clock `mono_at_epoch_s` at t = 0 and host wall
  clock error `host_clock_error_s`.
- SDR: `beacons.synth` writes `sdr.cu8` with `cfg.n_satellites` Starlink tones at the
  carrier `f_c_hz` (C/N0 `cn0_dbhz`, LNB LO `lnb_lo_hz` with error `lo_offset_hz`)
  starting at t = `sdr_start_s`, the SDR tuned to f_c - LNB LO.
"""
from __future__ import annotations

import dataclasses
import datetime as _dt
import math
import shutil
import warnings
from pathlib import Path
from typing import Callable

import numpy as np

from leonav.hardware.clock import utc_unix
from leonav.hardware.fake_session import GnssOutput, HostTiming, ImuOutput, SdrOutput, write_fake_session
from leonav.hardware.sdr import capture as sdr_capture
from leonav_runtime.core import navfuncs
from leonav_runtime.orbits import geometry
from leonav_runtime.simulation import simulate
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gen.constants import STARLINK_BEACON_HZ
from leonav_runtime.inputs import LO_RANDOM_WALK_HZ2_S
from leonav_runtime.common.output import write_csv, write_json

ROCHESTER = (43.0848638, -77.6786127, 170.0)   # the paper's site: deg, deg, m (ellipsoidal)
PAPER_EPOCH = _dt.datetime(2026, 2, 23, 12, 0, tzinfo=_dt.timezone.utc)
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
    f_c_hz: float = STARLINK_BEACON_HZ     # beacon carrier (tone RF frequency), also the recorder's RF centre
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
    ahrs_rpy_rad: np.ndarray   # (n, 3) roll/pitch/yaw the sensor reports at samples 1..n, rad
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
    from leonav_runtime.scenarios.load import scenario_from_dict

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
    from leonav_runtime.core.params import build_params

    if cfg.imu_rate_hz <= 0 or cfg.gnss_rate_hz <= 0 or cfg.seconds <= 1.0:
        raise UserInputError("synthetic session: expected seconds > 1 and positive IMU/GNSS rates")
    step = cfg.imu_rate_hz / cfg.gnss_rate_hz
    if abs(step - round(step)) > 1e-9:
        raise UserInputError(f"synthetic session: GNSS rate {cfg.gnss_rate_hz} Hz must divide the IMU rate "
                             f"{cfg.imu_rate_hz} Hz")
    scn = _scenario(cfg)
    params = np.array(build_params(scn.lat_rad, scn.lon_rad, scn.alt_m, imu=WT901,
                                   q_blo=LO_RANDOM_WALK_HZ2_S, f_c_hz=cfg.f_c_hz))
    nav = nav or navfuncs.NavFunctions()
    nav.params = params
    t, x_true, u_true = simulate.truth(scn, params, nav)
    L = nav.layout
    rng = np.random.default_rng(cfg.seed)
    n, dt = u_true.shape[0], 1.0 / cfg.imu_rate_hz
    b_a, b_g = simulate.bias_walks(rng, WT901, n, dt)
    x_true = x_true.copy()
    x_true[:, L.X_B_A_SLICE], x_true[:, L.X_B_G_SLICE] = b_a, b_g
    u = simulate.measured_increments(rng, WT901, u_true, b_a, b_g, dt)

    rpy = nav.euler_from_quat(x_true[1:, L.X_Q_NB_SLICE])
    ahrs_err = np.radians([cfg.ahrs_sigma_rp_deg, cfg.ahrs_sigma_rp_deg, cfg.ahrs_sigma_yaw_deg])
    ahrs = rpy + ahrs_err * rng.standard_normal(3) + np.radians(0.02) * rng.standard_normal((n, 3))

    k_fix = np.arange(int(round(step)), n + 1, int(round(step)))
    p = x_true[k_fix, L.X_P_ENU_SLICE]
    v = x_true[k_fix, L.X_V_ENU_SLICE]
    sig = np.array([cfg.fix_sigma_en_m, cfg.fix_sigma_en_m, cfg.fix_sigma_u_m])
    fix_enu = p + sig * rng.standard_normal(p.shape)
    fix_vel = v[:, :2] + cfg.speed_sigma_mps * rng.standard_normal((k_fix.size, 2))
    sent = t[k_fix] >= cfg.gnss_start_s - 1e-9      # drawn for every epoch: same noise whatever the start
    return {"params": params, "t_imu": t, "x_true": x_true, "u_meas": u, "ahrs_rpy_rad": ahrs,
            "fix_t": t[k_fix][sent], "fix_enu": fix_enu[sent], "fix_vel_en": fix_vel[sent], "scn": scn}


# ------------------------------------------------------------------ the session folder


def builtin_starlink(epoch_utc: _dt.datetime):
    """The built-in Walker Starlink set generated at the UTC minute nearest to `epoch_utc`
    (`leonav replay` uses the same rule on the capture start, so a synthetic session and its
    replay agree as long as the mapped start is within 30 s of the true one)."""
    from leonav_runtime.orbits import parse_elements_text, starlink_walker_tle

    minute = (epoch_utc.astimezone(_dt.timezone.utc) + _dt.timedelta(seconds=30)).replace(second=0, microsecond=0)
    return parse_elements_text(starlink_walker_tle(minute), "<leonav starlink walker>", constellation="starlink")


def capture_config(cfg: SynthSessionConfig):
    """What the session's capture is synthesized from: (SdrSettings, beacons.synth.SynthConfig,
    Site, start UTC); `beacons.synth.build_truth(elements, site, start, synth_cfg)` gives its
    truth again (the tones' baseband frequency, hence their phase)."""
    from leonav_runtime.beacons import synth
    from leonav_runtime.beacons.predict import Site

    settings = sdr_capture.SdrSettings(rf_center_hz=cfg.f_c_hz, lnb_lo_hz=cfg.lnb_lo_hz,
                                       sample_rate_hz=cfg.sdr_rate_hz, gain_db=30.0)
    start = cfg.epoch_utc + _dt.timedelta(seconds=cfg.sdr_start_s)
    duration = cfg.seconds - cfg.sdr_start_s - 0.05
    scfg = synth.SynthConfig(duration_s=duration, sample_rate_hz=cfg.sdr_rate_hz, center_freq_hz=settings.if_hz,
                             lnb_lo_hz=settings.lnb_lo_hz, f_c_hz=cfg.f_c_hz, cn0_dbhz=cfg.cn0_dbhz,
                             lo_offset_hz=cfg.lo_offset_hz,
                             n_satellites=cfg.n_satellites, seed=cfg.seed)
    site = Site(math.radians(cfg.lat_deg), math.radians(cfg.lon_deg), cfg.alt_m)
    return settings, scfg, site, start


def _write_iq(folder: Path, cfg: SynthSessionConfig, elements, progress) -> tuple[SdrOutput, dict]:
    """sdr.cu8 with the beacon tones (`beacons.synth`); returns what the recorder's metadata needs and the
    capture's truth."""
    from leonav_runtime.beacons import synth

    settings, scfg, site, start = capture_config(cfg)
    data = folder / "sdr.cu8"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # stale-element warnings: the replay reports them
        try:
            info, truth = synth.write_synthetic_capture(data, elements, site, start, scfg, "cu8", progress=progress)
        except ValueError as exc:
            raise UserInputError(f"synthetic session SDR: {exc}") from None
    Path(str(data) + ".json").unlink(missing_ok=True)    # the recorder writes SigMF metadata instead
    return SdrOutput(settings, info.n_samples, cfg.sdr_start_s), truth


def _device_outputs(cfg: SynthSessionConfig, sim: dict, nav: navfuncs.NavFunctions) -> tuple[GnssOutput, ImuOutput]:
    """What the receiver and the IMU report (floats), handed to the hardware writer."""
    L = nav.layout
    lat0, lon0, h0 = math.radians(cfg.lat_deg), math.radians(cfg.lon_deg), cfg.alt_m
    r0 = geometry.geodetic_to_ecef(lat0, lon0, h0)
    lat, lon, h = geometry.ecef_to_geodetic(geometry.enu_to_ecef(sim["fix_enu"], r0, lat0, lon0))
    gnss = GnssOutput(sim["fix_t"], np.atleast_1d(lat), np.atleast_1d(lon), np.atleast_1d(h), sim["fix_vel_en"],
                      cfg.fix_sigma_en_m, cfg.fix_sigma_u_m, cfg.geoid_sep_m, cfg.gga_no_altitude_s)
    dt = 1.0 / cfg.imu_rate_hz
    u = sim["u_meas"]
    imu = ImuOutput(sim["t_imu"][1:], u[:, L.U_DTHETA_B_SLICE] / dt, u[:, L.U_DVEL_B_SLICE] / dt, sim["ahrs_rpy_rad"])
    return gnss, imu


def _truth_rows(cfg: SynthSessionConfig, sim: dict, nav: navfuncs.NavFunctions) -> list[list]:
    L = nav.layout
    lat0, lon0, h0 = math.radians(cfg.lat_deg), math.radians(cfg.lon_deg), cfg.alt_m
    x = sim["x_true"]
    r = geometry.enu_to_ecef(x[:, L.X_P_ENU_SLICE], geometry.geodetic_to_ecef(lat0, lon0, h0), lat0, lon0)
    lat, lon, h = geometry.ecef_to_geodetic(r)
    rpy = nav.euler_from_quat(x[:, L.X_Q_NB_SLICE])
    t0 = utc_unix(cfg.epoch_utc)
    return [[t0 + t, t, math.degrees(lat[k]), math.degrees(lon[k]), h[k], *x[k, L.X_P_ENU_SLICE],
             *x[k, L.X_V_ENU_SLICE], *rpy[k], *x[k, L.X_B_A_SLICE], *x[k, L.X_B_G_SLICE]]
            for k, t in enumerate(sim["t_imu"])]


def write_synthetic_session(folder: str | Path, cfg: SynthSessionConfig | None = None, elements=None,
                            overwrite: bool = False, progress: Callable[[int], None] | None = None,
                            nav: navfuncs.NavFunctions | None = None,
                            extra_gnss: list[tuple[float, bytes]] = ()) -> SyntheticSession:
    """Write a synthetic session (see the module doc) into `folder`.

    elements: Starlink ElementSet for the tones (default: `builtin_starlink(cfg.epoch_utc)`).
    progress(n): called with IQ samples written. extra_gnss: (time s, bytes) the receiver
    sends besides its NMEA (e.g. UBX RXM-RAWX and RXM-SFRBX frames made by the caller).
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
    if elements is None and cfg.sdr:
        elements = builtin_starlink(cfg.epoch_utc)
    sdr, sdr_truth = _write_iq(folder, cfg, elements, progress) if cfg.sdr else (None, None)
    gnss, imu = _device_outputs(cfg, sim, nav)
    timing = HostTiming(cfg.gnss_baud, cfg.imu_baud, cfg.gnss_latency_s, cfg.imu_latency_s, cfg.host_read_s,
                        cfg.mono_at_epoch_s, cfg.host_clock_error_s)
    write_fake_session(folder, cfg.epoch_utc, cfg.seconds, gnss, imu, timing, np.random.default_rng([cfg.seed, 7]),
                       sdr, extra_gnss)

    write_csv(folder / "truth.csv", TRUTH_COLUMNS, _truth_rows(cfg, sim, nav))
    sdr_info = sdr_truth.describe() if sdr_truth is not None else {}
    write_json(folder / "synthetic.json", {
        "note": "synthetic session written by leonav_runtime.simulation.session_synth; truth.csv and this file are not "
                "written by `leonav record`",
        "config": dataclasses.asdict(cfg), "sdr_truth": sdr_info,
        "element_source": "built-in Walker constellation at the nearest UTC minute" if elements is not None
        and getattr(elements, "names", [""])[0].startswith("STARLINK-W") else "given element sets",
    })
    return SyntheticSession(folder, cfg, sim["params"], sim["t_imu"], sim["x_true"], sim["u_meas"],
                            sim["ahrs_rpy_rad"], sim["fix_t"], sim["fix_enu"], sim["fix_vel_en"], sdr_info, elements)
