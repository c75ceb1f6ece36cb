"""Sanity checks of a dataset against physics, naming the description key that is likely wrong.

Each raises one `UserInputError` line: the key (or command-line option), what was measured
and what was expected. Thresholds are loose on purpose: they catch a wrong unit, time base
or CRS (factors of 10..1000, kilometres), not a poor sensor.
- IMU units: the median specific-force magnitude is g within a factor 2 (any vehicle that
  is not in free fall or a centrifuge); the sample rate is 1 Hz..20 kHz; the 99th
  percentile rate magnitude is below 20 rad/s (deg/s read as rad/s is 57 times too big).
- Time overlap: the IMU (after time base and offset) and the fixes share some time.
- Reference: it overlaps the fixes in time, and its median horizontal distance to the
  fixes is below 100 m (swapped lat/lon, LLH read as ECEF, a wrong EPSG code: kilometres).
"""
from __future__ import annotations

import numpy as np

from leonav_runtime.common.errors import UserInputError

G_MPS2 = 9.80665
RATE_HZ = (1.0, 20000.0)
MAX_RATE_RADPS = 20.0
MAX_REFERENCE_DISTANCE_M = 100.0


def imu_units(spec, t_s: np.ndarray, w_radps: np.ndarray, f_mps2: np.ndarray, path) -> None:
    """Units of the IMU samples as read (t s, w rad/s, f m/s^2) against physics (module doc)."""
    s = spec["imu"]
    if t_s.size > 2:
        dt = float(np.median(np.diff(t_s)))
        rate = 1.0 / dt if dt > 0 else float("inf")
        if not RATE_HZ[0] <= rate <= RATE_HZ[1]:
            raise UserInputError(f"{spec.where('imu', 'time_unit')} = {s['time_unit']!r}: {path} gives a sample "
                                 f"rate of {rate:.3g} Hz, expected {RATE_HZ[0]:g}..{RATE_HZ[1]:g} Hz: check the unit")
    f = float(np.median(np.linalg.norm(f_mps2, axis=1)))
    if not 0.5 * G_MPS2 <= f <= 2 * G_MPS2:
        raise UserInputError(f"{spec.where('imu', 'accel_unit')} = {s['accel_unit']!r}: the median specific force "
                             f"of {path} is {f:.3g} m/s^2, expected about g = 9.81 m/s^2: check the unit")
    w = float(np.percentile(np.linalg.norm(w_radps, axis=1), 99))
    if w > MAX_RATE_RADPS:
        raise UserInputError(f"{spec.where('imu', 'gyro_unit')} = {s['gyro_unit']!r}: 1 % of the rates of {path} "
                             f"exceed {w:.3g} rad/s, expected below {MAX_RATE_RADPS:g} rad/s: check the unit")


def time_overlap(spec, imu_t_s: np.ndarray, fix_t_s: np.ndarray, offset_s: float) -> None:
    """The IMU and the fixes share time on the run axis (module doc)."""
    if imu_t_s[-1] <= fix_t_s[0] or imu_t_s[0] >= fix_t_s[-1]:
        raise UserInputError(
            f"{spec.where('imu', 'time_base')} = {spec['imu']['time_base']!r}, time_offset_s = {offset_s:g}: the IMU "
            f"spans {imu_t_s[0]:.6g}..{imu_t_s[-1]:.6g} s and the fixes 0..{fix_t_s[-1]:.6g} s after the first fix: "
            "no overlap; expected unix time ('unix') or seconds from the first fix ('first_fix')")


def reference(ref, fixes, what: str) -> None:
    """The reference overlaps the fixes in time and lies near them (module doc); `what` names
    the keys or options that describe the reference."""
    both = (fixes.t >= ref.t[0]) & (fixes.t <= ref.t[-1])
    if not both.any():
        raise UserInputError(f"{what}: the reference spans {ref.t[0]:.6g}..{ref.t[-1]:.6g} s after the first fix, "
                             f"the fixes 0..{fixes.t[-1]:.6g} s: no overlap; expected unix time in seconds "
                             "(time column and unit)")
    t = fixes.t[both]
    p = np.column_stack([np.interp(t, ref.t, ref.p_enu_m[:, j]) for j in range(2)])
    d = float(np.median(np.hypot(*(p - fixes.p_enu_m[both, :2]).T)))
    if d > MAX_REFERENCE_DISTANCE_M:
        raise UserInputError(f"{what}: the reference is {d:.3g} m from the GNSS fixes (median), expected metres: "
                             "check the CRS and the column order (swapped lat/lon? ECEF read as lat/lon/h?)")


def until(t_end_s: float, first_s: float, what: str) -> None:
    """--until leaves something to run and score: t_end_s must exceed `first_s`."""
    if t_end_s <= first_s:
        raise UserInputError(f"--until {t_end_s:g}: {what} at {first_s:.6g} s after the first fix: expected "
                             f"--until > {first_s:.6g}")
