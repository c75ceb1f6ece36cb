"""Sanity checks of a dataset against physics, naming the description key that is likely wrong.

Each raises one `UserInputError` line: the key (or command-line option), what was measured
and what was expected. Thresholds are loose on purpose: they catch a wrong unit, time base
or CRS (factors of 10..1000, kilometres), not a poor sensor.
- IMU units: the median specific-force magnitude is g within a factor 2 (any vehicle that
  is not in free fall or a centrifuge); the sample rate is 1 Hz..20 kHz; the 99th
  percentile rate magnitude is below 20 rad/s (deg/s read as rad/s is 57 times too big).
- Time overlap: the IMU (after time base and offset) and the fixes share some time; a boot
  clock's mapping (`clock_pair`, `time_offset_s`) puts the IMU over the fixes' span.
- Gyro unit against the GNSS course: over 5 s windows of driving, the heading change the gyro
  integrates about the measured gravity direction (axes and mounting do not matter) against
  the change of the GNSS course. The windows are those where the gyro turns most (its top
  quarter: a ranking no unit changes); when the GNSS course turns with it there (same sign in
  3 of 4 windows, median turn >= 15 deg), the median ratio must lie in 1/8..8 (deg/s declared
  for rad/s data gives 1/57, the reverse 57). Without such turns, at rest (1 s blocks whose
  specific force varies by less than 0.05 m/s^2): the median |mean rate| must lie between
  1/20 of the Earth rate and 0.5 rad/s (a consumer gyro's bias stays far below, a good gyro
  reads about 7.3e-5 rad/s). The measured ratio or rate goes into `counts["imu"]`.
- Reference: it overlaps the fixes in time, and its median horizontal distance to the
  fixes is below 100 m (swapped lat/lon, LLH read as ECEF, a wrong EPSG code: kilometres).
"""
from __future__ import annotations

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.scenarios.load import show_value

G_MPS2 = 9.80665
RATE_HZ = (1.0, 20000.0)
MAX_RATE_RADPS = 20.0
MAX_REFERENCE_DISTANCE_M = 100.0
EARTH_RATE_RADPS = 7.292115e-5
GYRO_COURSE_RATIO = (1 / 8, 8.0)
TURN_WINDOW_S = 5.0
MIN_TURN_RAD = np.radians(15.0)
MOVING_MPS = 0.2
REST_RATE_RADPS = (EARTH_RATE_RADPS / 20, 0.5)


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


def clock_mapping(spec, key: str, imu_unix_s: np.ndarray, fix_unix_s: np.ndarray) -> None:
    """A boot clock mapped by `[imu] key` (clock_pair or time_offset_s) puts the IMU (unix s) over
    some of the fixes' span (unix s)."""
    if imu_unix_s[-1] <= fix_unix_s[0] or imu_unix_s[0] >= fix_unix_s[-1]:
        raise UserInputError(
            f"{spec.where('imu', key)} = {show_value(spec['imu'][key])} (time_base = 'boot'): the IMU spans unix "
            f"{imu_unix_s[0]:.3f}..{imu_unix_s[-1]:.3f} s, the fixes {fix_unix_s[0]:.3f}..{fix_unix_s[-1]:.3f} s: no "
            "overlap; expected boot and unix readings taken at the same moment (clock_pair = [boot_s, unix_s]) or "
            "unix - boot in s (time_offset_s)")


def _course(fixes, window_s: float = 2.0, rate_hz: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
    """(t s, unwrapped course rad) of the GNSS velocity (positions differenced over window_s, on a
    regular grid) where the speed exceeds MOVING_MPS."""
    t = np.arange(fixes.t[0] + window_s / 2, fixes.t[-1] - window_s / 2, 1.0 / rate_hz)
    if t.size < 2:
        return t[:0], t[:0]
    d = np.column_stack([np.interp(t + window_s / 2, fixes.t, fixes.p_enu_m[:, j])
                         - np.interp(t - window_s / 2, fixes.t, fixes.p_enu_m[:, j]) for j in range(2)]) / window_s
    ok = np.hypot(d[:, 0], d[:, 1]) > MOVING_MPS
    return t[ok], np.unwrap(np.arctan2(d[ok, 1], d[ok, 0]))


def _up_rate(imu) -> np.ndarray:
    """Rate (rad/s) about the measured up direction (the 1 s mean specific force) per IMU sample."""
    n = max(1, int(round(1.0 / float(np.median(np.diff(imu.t))))))
    kernel = np.ones(n) / n
    f = np.column_stack([np.convolve(imu.f_b_mps2[:, j], kernel, "same") for j in range(3)])
    return np.sum(imu.w_b_radps * f, axis=1) / np.maximum(np.linalg.norm(f, axis=1), 1e-9)


def _turn_ratio(imu, fixes) -> float | None:
    """Median |gyro heading change| / |GNSS course change| over the windows where the gyro turns
    most, when the GNSS course turns there too (module doc); None when it cannot be said."""
    t_c, c = _course(fixes)
    inside = (t_c > imu.t[0]) & (t_c < imu.t[-1])
    t_c, c = t_c[inside], c[inside]
    if t_c.size < 2:
        return None
    wu = _up_rate(imu)
    psi = np.concatenate([[0.0], np.cumsum(0.5 * (wu[1:] + wu[:-1]) * np.diff(imu.t))])
    pairs, a = [], 0
    while a < t_c.size:
        b = int(np.searchsorted(t_c, t_c[a] + TURN_WINDOW_S))
        if b >= t_c.size:
            break
        if np.all(np.diff(t_c[a:b + 1]) < 0.5):     # driving all through the window
            pairs.append((c[b] - c[a], np.interp(t_c[b], imu.t, psi) - np.interp(t_c[a], imu.t, psi)))
        a = b
    if len(pairs) < 8:
        return None
    dc, dg = np.array(pairs).T
    top = np.abs(dg) >= np.percentile(np.abs(dg), 75)
    dc, dg = dc[top], dg[top]
    if np.mean(np.sign(dc) == np.sign(dg)) < 0.75 or np.median(np.abs(dc)) < MIN_TURN_RAD:
        return None
    return float(np.median(np.abs(dg)) / np.median(np.abs(dc)))


def _rest_rate(imu) -> float | None:
    """Median over 1 s blocks at rest of |mean rate| (rad/s), None with fewer than 5 such blocks."""
    n = max(1, int(round(1.0 / float(np.median(np.diff(imu.t))))))
    m = imu.t.size // n
    if m == 0:
        return None
    f = imu.f_b_mps2[:m * n].reshape(m, n, 3)
    still = f.std(axis=1).max(axis=1) < 0.05
    if still.sum() < 5:
        return None
    w = imu.w_b_radps[:m * n].reshape(m, n, 3)[still].mean(axis=1)
    return float(np.median(np.linalg.norm(w, axis=1)))


def gyro_unit(spec, imu, fixes, counts: dict) -> None:
    """The gyro unit against the GNSS course change over turns, else against the Earth rate at
    rest (module doc); `imu` on the fixes' axis (s), body FLU."""
    s = spec["imu"]
    where = f"{spec.where('imu', 'gyro_unit')} = {s['gyro_unit']!r}"
    ratio = _turn_ratio(imu, fixes)
    if ratio is not None:
        counts.setdefault("imu", {})["gyro_vs_gnss_course_ratio"] = ratio
        if not GYRO_COURSE_RATIO[0] <= ratio <= GYRO_COURSE_RATIO[1]:
            raise UserInputError(f"{where}: over the turns the gyro integrates {ratio:.3g} times the change of the "
                                 f"GNSS course, expected about 1 (deg/s declared for rad/s gives 1/57, the reverse "
                                 "57): check the unit")
        return
    rest = _rest_rate(imu)
    if rest is None:
        return
    counts.setdefault("imu", {})["rate_at_rest_radps"] = rest
    if not REST_RATE_RADPS[0] <= rest <= REST_RATE_RADPS[1]:
        raise UserInputError(f"{where}: at rest the gyro reads {rest:.3g} rad/s, expected "
                             f"{REST_RATE_RADPS[0]:.2g}..{REST_RATE_RADPS[1]:g} rad/s (the Earth turns at "
                             f"{EARTH_RATE_RADPS:.3g} rad/s, gyro biases add to it): check the unit")
