"""The IMU samples of a dataset description: one file, or a gyro file and an accelerometer
file with their own time columns, put on one time axis in the IMU's time base.

- Units: time column * `time_unit`, then the time base (`timebase.to_base`): unix s for unix,
  gps_week_tow, gps_seconds and boot with a clock pair; as it is for first_fix and for boot
  mapped by `time_offset_s`. Rates * `gyro_unit` -> rad/s, specific force * `accel_unit` -> m/s^2.
- Two files (`accel_file`): each stream's bad rows are skipped on its own (the accelerometer's
  counted under `counts["imu"]["accel_file"]`); the accelerometer is interpolated linearly onto
  the gyro times inside the span both cover. Rows outside that span are counted
  (`rows_outside_common_span`, both files), gyro rows inside an accelerometer gap (a step over
  2.5 of its median intervals) too (`rows_in_accel_gaps`), and skipped, so the gap stays a gap.
  Spans that share less than half of the shorter one: one error naming both files.
- Clipping (`accel_range_mps2`, `gyro_range_radps`): a sample at 0.999 of full scale is
  skipped (`rows_clipped`); an accelerometer sample clipped next to a gyro time clips that row.
- Time jumps (`readers.time_jumps`) are counted (`time_jumps`) and become gaps (`gaps`).
"""
from __future__ import annotations

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.dataset import checks, readers, timebase
from leonav_runtime.dataset.spec import ACCEL_UNITS, GYRO_UNITS, TIME_UNITS, DatasetSpec

GAP_INTERVALS = 2.5
"""A step longer than this many median intervals is a gap (counted)."""


def _vehicle_flu(raw: np.ndarray, axis_map, frame: str) -> np.ndarray:
    """Sensor columns (n, 3) -> vehicle frame by the axis map -> body FLU."""
    out = np.column_stack([sign * raw[:, axis] for axis, sign in axis_map])
    if frame == "FRD":
        out[:, 1:] *= -1.0
    return out


def _stream(spec: DatasetSpec, path, time_key: str, data_key: str, scale: float, full_scale: float,
            array_key: str = "array") -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """(t s in the time base, values (n, k) SI, times of the clipped rows, counts) of one IMU
    file's good rows, in time order (repeated or earlier time stamps skipped)."""
    s = spec["imu"]
    wk = timebase.week_key(s)
    names = s[data_key] if data_key != "both" else s["gyro_columns"] + s["accel_columns"]
    keys = ([data_key] * len(names) if data_key != "both"
            else ["gyro_columns"] * len(s["gyro_columns"]) + ["accel_columns"] * len(s["accel_columns"]))
    cols = [(time_key, s[time_key])] + wk + list(zip(keys, names))
    data = readers.read_source(path, s, cols, array_key)
    need = 1 + len(wk) + (6 if data_key == "both" else 3)
    if data.values.shape[1] != need:
        raise UserInputError(f"{path}: expected a time column and {need - 1 - len(wk)} data columns (x y z), got "
                             f"{data.values.shape[1] - 1 - len(wk)}")
    v = data.values
    t, n_bad = timebase.to_base(v[:, 0] * TIME_UNITS[s["time_unit"]], s, v[:, 1] if wk else None,
                                spec.where("imu", "time_base"))
    vals = v[:, 1 + len(wk):]
    if data_key == "both":
        vals = np.hstack([vals[:, :3] * GYRO_UNITS[s["gyro_unit"]], vals[:, 3:] * ACCEL_UNITS[s["accel_unit"]]])
    else:
        vals = vals * scale
    clipped = np.zeros(t.size, bool)
    ranges = ((s["gyro_range_radps"], slice(0, 3)), (s["accel_range_mps2"], slice(3, 6))) if data_key == "both" \
        else ((full_scale, slice(0, 3)),)
    for limit, cols_ in ranges:
        if limit > 0:
            clipped |= (np.abs(vals[:, cols_]) >= 0.999 * limit).any(axis=1)
    t_ok = np.where(clipped, np.nan, t)
    jumps = readers.time_jumps(t_ok)
    keep, order = readers.monotonic_rows(t_ok)
    counts = data.counts | order | ({"rows_bad_time_of_week": n_bad} if n_bad else {}) | jumps
    return t[keep], vals[keep], t[clipped], counts | {"rows_clipped": int(clipped.sum())}


def _merge(tg: np.ndarray, w: np.ndarray, ta: np.ndarray, f: np.ndarray, ta_clipped: np.ndarray, gyro_path,
           accel_path, counts: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Accelerometer samples (ta, f) interpolated onto the gyro times tg inside both spans (module doc)."""
    lo, hi = max(tg[0], ta[0]), min(tg[-1], ta[-1])
    shorter = min(tg[-1] - tg[0], ta[-1] - ta[0])
    if hi - lo < 0.5 * shorter or hi <= lo:
        raise UserInputError(f"{gyro_path} ([imu] file) spans {tg[0]:.9g}..{tg[-1]:.9g} s and {accel_path} "
                             f"([imu] accel_file) {ta[0]:.9g}..{ta[-1]:.9g} s: they share {max(hi - lo, 0):.3g} s, "
                             "less than half of the shorter record: expected simultaneous gyro and accelerometer "
                             "records (time columns, time_unit)")
    inside = (tg >= lo) & (tg <= hi)
    k = np.clip(np.searchsorted(ta, tg, side="left"), 1, ta.size - 1)
    exact = ta[np.clip(np.searchsorted(ta, tg), 0, ta.size - 1)] == tg
    step = ta[k] - ta[k - 1]
    in_gap = inside & ~exact & (step > GAP_INTERVALS * float(np.median(np.diff(ta))))
    # a clipped accelerometer sample lies inside one kept interval: the gyro rows of that interval are clipped
    hit = np.zeros(ta.size + 1, bool)
    hit[np.searchsorted(ta, ta_clipped[np.isfinite(ta_clipped)])] = True
    clipped = inside & ~exact & hit[k]
    counts["rows_outside_common_span"] = int((~inside).sum() + ((ta < lo) | (ta > hi)).sum())
    counts["rows_in_accel_gaps"] = int(in_gap.sum())
    counts["rows_clipped_accel"] = int(clipped.sum())
    use = inside & ~in_gap & ~clipped
    f_on = np.column_stack([np.interp(tg[use], ta, f[:, j]) for j in range(3)])
    return tg[use], w[use], f_on


def read_imu(spec: DatasetSpec, counts: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t s in the IMU's time base, w rad/s FLU, f m/s^2 FLU) of the good IMU rows (module doc)."""
    s = spec["imu"]
    path = readers.resolve(spec.data_dir / s["file"], "IMU", spec.where("imu", "file"), spec.shared)
    if not s["accel_file"]:
        t, v, _, c = _stream(spec, path, "time_column", "both", 1.0, 0.0)
        w, f = v[:, :3], v[:, 3:]
        counts["imu"] = c
    else:
        apath = readers.resolve(spec.data_dir / s["accel_file"], "accelerometer", spec.where("imu", "accel_file"),
                                spec.shared)
        tg, w, _, c = _stream(spec, path, "time_column", "gyro_columns", GYRO_UNITS[s["gyro_unit"]],
                                   s["gyro_range_radps"])
        ta, f, clip_a, ca = _stream(spec, apath, "accel_time_column", "accel_columns", ACCEL_UNITS[s["accel_unit"]],
                                    s["accel_range_mps2"], "accel_array")
        c["accel_file"] = ca
        counts["imu"] = c
        t, w, f = _merge(tg, w, ta, f, clip_a, path, apath, c)
    c = counts["imu"]
    if t.size < 2:
        raise UserInputError(f"{path}: fewer than 2 usable IMU rows: expected samples with increasing time")
    c["rows_used"] = int(t.size)
    checks.imu_units(spec, t, w, f, path)
    dt = np.diff(t)
    med = float(np.median(dt))
    gaps = dt > GAP_INTERVALS * med
    c |= {"rate_hz": 1.0 / med, "gaps": int(gaps.sum()), "gap_seconds": float(dt[gaps].sum())}
    return t, _vehicle_flu(w, s["axis_map"], s["frame"]), _vehicle_flu(f, s["axis_map"], s["frame"])
