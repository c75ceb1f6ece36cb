"""The filter's start: parameters p, initial state x0 and covariance P0.

- `filter_params`: p from the ENU origin, the IMU profile and the beacon carrier f_c
  (`leonav_runtime.core.params.build_params`, LO random walk `LO_RANDOM_WALK_HZ2_S`).
- `prior_sigmas`: 1-sigma per error state; navigation sigmas as given, IMU biases from the
  profile, every other block its registry prior (`core.model.prior_sigmas`; they only set how
  fast the filter locks; the simulator draws its truth from the same prior).
- `Prior`: x0 and P0 given (the simulator: a draw around its truth).
- `FirstFixPrior`: x0 and P0 from the data (a recorded session, a dataset): position and
  horizontal velocity of the first usable GNSS fix, roll/pitch (and yaw unless given) the
  IMU's own angle output averaged over the first `attitude_window_s`, biases 0. The
  initializing fix is the first one from `fix_window_s` before the first IMU interval on;
  if it comes more than `fix_max_delay_s` after that interval's start, the filter starts
  at the fix instead (a moving receiver is not given a late position): earlier intervals
  are dropped and the one spanning the fix is cut at it. Without a fix the position is
  the origin (sigma `no_fix_position_sigma_m`).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from leonav_runtime.core import model, navfuncs
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.inputs.tables import FixTable, ImuTable
from leonav_runtime.core.params import DEFAULT_Q_BLO_HZ2_S, ImuProfile, build_params

LO_RANDOM_WALK_HZ2_S = DEFAULT_Q_BLO_HZ2_S   # LO drift PSD used by filter and truth


def filter_params(origin, profile: ImuProfile, f_c_hz: float, values: dict[str, float] | None = None) -> np.ndarray:
    """Parameter vector (NP,) for the ENU origin (lat rad, lon rad, h m), an IMU profile, the
    beacon carrier f_c (Hz) and any registry parameter by name (`values`, e.g. a scenario's
    magnetic declination); a UserInputError names a non-finite input."""
    lat0, lon0, h0 = origin
    params = np.array(build_params(lat0, lon0, h0, imu=profile, q_blo=LO_RANDOM_WALK_HZ2_S, f_c_hz=f_c_hz,
                                   values=values))
    if not np.all(np.isfinite(params)):
        raise UserInputError(f"filter parameters: non-finite value from origin (lat, lon rad, h m) {tuple(origin)}, "
                             f"f_c_hz {f_c_hz}, IMU profile {profile.name}: expected finite numbers")
    return params


def prior_sigmas(layout, profile, position_m, velocity_mps, attitude_rad, overrides: dict | None = None) -> np.ndarray:
    """1-sigma of the filter prior per error state (NDX,): navigation sigmas as given
    (scalars or 3-vectors; m, m/s, rad), IMU biases from the profile, every other block its
    registry prior or `overrides` ({error-state block name: sigma})."""
    return model.prior_sigmas(layout, profile, position_m, velocity_mps, attitude_rad, overrides)


@dataclasses.dataclass
class Prior:
    """x0 (NX,) and P0 (NDX, NDX) at the filter start `t_start_s` (s; None: the start of the
    first IMU interval); `init` describes where they came from."""

    x0: np.ndarray
    P0: np.ndarray
    init: dict = dataclasses.field(default_factory=dict)
    t_start_s: float | None = None


@dataclasses.dataclass
class FirstFixPrior:
    """How to start from the data (module doc). Angles in rad, yaw from East towards North;
    the *_source texts describe the inputs in `FilterInputs.init`."""

    profile: ImuProfile
    yaw_rad: float | None = None
    velocity_sigma_mps: float = 0.5
    roll_pitch_sigma_rad: float = math.radians(0.5)
    yaw_sigma_given_rad: float = math.radians(2.0)
    yaw_sigma_sensor_rad: float = math.radians(5.0)
    attitude_window_s: float = 1.0
    fix_window_s: float = 0.2
    fix_max_delay_s: float = 0.05
    no_fix_position_sigma_m: float = 10.0
    attitude_source: str = "the IMU's angle output"
    yaw_given_source: str = "given"
    velocity_source: str = "the initializing fix's horizontal velocity"
    fix_latency_sigma_s: float = 0.0   # > 0: the fix latency state dt_fix is estimated from 0 with this sigma


def _circular_mean(a: np.ndarray) -> float:
    return float(np.arctan2(np.mean(np.sin(a)), np.mean(np.cos(a))))


def start_and_init_fix(spec: FirstFixPrior, imu: ImuTable, fixes: FixTable, notes: list[str]) -> tuple[float, int]:
    """(filter start time s, index of the initializing fix or -1); module doc."""
    t_first = imu.t_first
    cand = np.flatnonzero(fixes.t >= t_first - spec.fix_window_s)
    if cand.size == 0:
        return t_first, -1
    k = int(cand[0])
    t_fix = float(fixes.t[k])
    if t_fix <= t_first + spec.fix_max_delay_s:
        return t_first, k
    if t_fix >= imu.t[-1]:
        notes.append(f"init: the first usable GNSS fix (t={t_fix:.3f} s) comes after the last IMU sample "
                     f"(t={imu.t[-1]:.3f} s): the position starts at the origin")
        return t_first, -1
    notes.append(f"init: the first usable GNSS fix comes {t_fix - t_first:.3f} s after the first IMU interval's "
                 f"start (more than {spec.fix_max_delay_s:g} s): the filter starts at that fix, earlier IMU data "
                 "dropped")
    return t_fix, k


def first_fix_prior(spec: FirstFixPrior, imu: ImuTable, fixes: FixTable | None, nav: navfuncs.NavFunctions,
                    notes: list[str]) -> tuple[Prior, ImuTable, int, int]:
    """(prior, IMU table from the start on, index of the initializing fix or -1, IMU intervals
    dropped before the start). The initializing fix is not to be applied again as a
    measurement (its error would count twice)."""
    L = nav.layout
    fixes = FixTable.empty() if fixes is None else fixes
    t_first = imu.t_first
    t_start, init_fix = start_and_init_fix(spec, imu, fixes, notes)
    imu, n_before = imu.from_time(t_start)
    if imu.rpy_rad is None:
        raise UserInputError(f"{ImuTable.NAME}: rpy_rad: missing: expected the IMU's angle output (n, 3) rad "
                             "to initialize roll/pitch")
    x0 = np.zeros(L.NX)
    init: dict = {"start_s": t_start}
    if init_fix >= 0:
        x0[L.X_P_ENU_SLICE] = fixes.p_enu_m[init_fix]
        pos_sigma = fixes.sigma_enu_m[init_fix]
        init["position"] = f"fix at t={fixes.t[init_fix]:.3f} s (not applied again as a measurement)"
        v = fixes.v_en_mps[init_fix]
        if np.all(np.isfinite(v)):
            x0[L.X_V_ENU_SLICE][:2] = v
            init["velocity"] = f"{spec.velocity_source}, vertical 0"
        else:
            init["velocity"] = "0 (no velocity in the initializing fix)"
    else:
        pos_sigma = np.full(3, spec.no_fix_position_sigma_m)
        init["position"] = "origin (no fix)"
        init["velocity"] = "0"
    init["start"] = (f"the initializing fix ({n_before} IMU interval(s) before it dropped, the next one cut)"
                     if t_start > t_first else "start of the first IMU interval")
    first = imu.t <= imu.t[0] + spec.attitude_window_s
    roll, pitch = _circular_mean(imu.rpy_rad[first, 0]), _circular_mean(imu.rpy_rad[first, 1])
    level = nav.level(imu.f_b_mps2[first].mean(axis=0))
    if spec.yaw_rad is not None:
        yaw, yaw_sig, yaw_src = spec.yaw_rad, spec.yaw_sigma_given_rad, spec.yaw_given_source
    else:
        yaw, yaw_sig = _circular_mean(imu.rpy_rad[first, 2]), spec.yaw_sigma_sensor_rad
        yaw_src = f"{spec.attitude_source} (the sensor's own yaw reference)"
    x0[L.X_Q_NB_SLICE] = nav.quat_from_euler(np.array([roll, pitch, yaw]))[0]
    rp = spec.roll_pitch_sigma_rad
    overrides = {"ddt_fix": spec.fix_latency_sigma_s} if spec.fix_latency_sigma_s > 0 else None
    sig0 = prior_sigmas(L, spec.profile, pos_sigma, spec.velocity_sigma_mps, [rp, rp, yaw_sig], overrides)
    if overrides:
        init["fix_latency"] = f"estimated (state dt_fix): prior 0 +- {spec.fix_latency_sigma_s:g} s"
    init |= {"roll_pitch": f"{spec.attitude_source} averaged over the first {spec.attitude_window_s:g} s",
             "yaw": yaw_src, "rpy_deg": np.degrees([roll, pitch, yaw]),
             "accelerometer_leveling_roll_pitch_deg": np.degrees(level),
             "sigma0": {"position_m": pos_sigma, "velocity_mps": spec.velocity_sigma_mps,
                        "roll_pitch_deg": math.degrees(rp), "yaw_deg": math.degrees(yaw_sig)},
             "imu_profile": {"name": spec.profile.name, "vrw": spec.profile.vrw, "arw": spec.profile.arw}}
    return Prior(x0, np.diag(sig0**2), init, t_start), imu, init_fix, n_before
