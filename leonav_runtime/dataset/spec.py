"""Dataset description files (TOML): which files and columns hold the IMU, the GNSS fixes and
the reference trajectory, in which units, axes and time base; how to run and score them.

Validated like scenarios (`scenario.check_value`): one `UserInputError` naming the file,
the section and the key, with what was expected. Paths are relative to the `[data] dir`,
itself relative to the TOML file; `{shared}` in it is `$LEONAV_SHARED_DATA`, else the
`shared/data` folder beside the source checkout or beside the folder the command runs from (the project's public fixtures). The schema with
every key, unit and default is `SCHEMA` (and docs/datasets.md).
"""
from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.core import model
from leonav_runtime.replay.options import LATENCY_PRIOR_SIGMA_S, LATENCY_RANDOM_WALK   # one default for every road
from leonav_runtime.scenarios.load import Field, check_numbers, check_tables, show_value, where_key
from leonav_runtime.common.toml_file import read_toml_file
from leonav_runtime.dataset.spec_sources import check_columns as _columns, finish_sources
from leonav_runtime.dataset.timebase import IMU_BASES, UNIX_BASES

REQ = ...
MAX_FILE_BYTES = 1_000_000
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
GYRO_UNITS = {"rad/s": 1.0, "deg/s": math.pi / 180}
ACCEL_UNITS = {"m/s^2": 1.0, "g": 9.80665}
BODY_FRAMES = ("FRD", "FLU")
MODES = ("fix+imu", "fix+imu+nhc", "fix+imu+nhc+zupt")
FORMATS = ("csv", "npy", "npz")
ATTITUDES = ("quat_enu", "quat_ned", "quat_ecef", "euler_deg")


def dataset_observable(o) -> bool:
    """What a dataset description gives the filter: GNSS fixes and velocity, motion constraints and
    the local sensors it names a section for."""
    return o.stream in ("fix", "vel") or o.table in ("constraint", "local")


def dataset_mode(name: str, where: str = "[filter] modes:") -> model.Mode:
    """A dataset mode (observables, record streams), or a UserInputError naming `where`."""
    return model.parse_mode(name, dataset_observable, where)
AXES = re.compile(r"^\s*[-+]?[xyz]\s*,\s*[-+]?[xyz]\s*,\s*[-+]?[xyz]\s*$")
Column = (str, int)   # a header name, or a 0-based column index
WEEK_KEYS = {"week_column": Field(Column, "-", default="", doc="gps_week_tow: column of full GPS week numbers "
                                  "(empty: gps_week)"),
             "gps_week": Field(int, "week", 0, 9999, default=0, doc="gps_week_tow without week_column: the GPS "
                               "week of the first row (0: none)")}

SCHEMA: dict[str, dict[str, Field]] = {
    "": {"name": Field(str, "-", default="dataset", doc="short name (results folder)"),
         "description": Field(str, "-", default="", doc="one line for the results")},
    "data": {"dir": Field(str, "-", default=".", doc="folder of the files; relative to this file; {shared} = "
                          "$LEONAV_SHARED_DATA or ../shared/data beside the repository")},
    "imu": {
        "file": Field(str, "-", default=REQ, doc="IMU samples (gyro and, without accel_file, accelerometer)"),
        "format": Field(str, "-", default="csv", choices=FORMATS + ("mat",), doc="csv, npy, npz or mat (scipy.io)"),
        "mat_struct": Field(str, "-", default="", doc="mat: struct holding the fields (empty: top level)"),
        "array": Field(str, "-", default="", doc="npz: the array (n, k) inside (empty: the only one)"),
        "accel_file": Field(str, "-", default="", doc="accelerometer samples in their own file (same format), "
                            "interpolated onto the gyro times; empty: in `file`"),
        "accel_time_column": Field(Column, "-", default=0, doc="time column of accel_file"),
        "accel_array": Field(str, "-", default="", doc="npz: the accelerometer's array (empty: `array`)"),
        "delimiter": Field(str, "-", default=",", doc="csv field separator"),
        "time_column": Field(Column, "-", default=0, doc="header name or 0-based index (mat: field name)"),
        "gyro_columns": Field(list, "-", default=REQ, doc="3 names or indices, sensor x y z (mat: one (n, 3) field)"),
        "accel_columns": Field(list, "-", default=REQ, doc="3 names or indices, sensor x y z"),
        "time_unit": Field(str, "-", default="s", choices=tuple(TIME_UNITS)),
        "gyro_unit": Field(str, "-", default="rad/s", choices=tuple(GYRO_UNITS)),
        "accel_unit": Field(str, "-", default="m/s^2", choices=tuple(ACCEL_UNITS)),
        "axes": Field(str, "-", default="x,y,z", doc="vehicle axes as signed sensor axes, e.g. '-y,x,z'"),
        "frame": Field(str, "-", default="FRD", choices=BODY_FRAMES, doc="vehicle frame `axes` gives"),
        "time_base": Field(str, "-", default="unix", choices=IMU_BASES, doc="unix, gps_week_tow, gps_seconds, "
                           "first_fix (s from the first GNSS fix) or boot (a monotonic clock: clock_pair or time_offset_s)"),
        **WEEK_KEYS,
        "clock_pair": Field(list, "s", default=[], doc="boot: [boot_s, unix_s], one pair of simultaneous readings"),
        "time_offset_s": Field((float, str), "s", default=0.0,
                               doc="added to the IMU time (+-3600 s; any size with boot); 'calibrate': estimated "
                               "from the gyro vs the GNSS course rate; 'calibrate_reference': vs the reference yaw "
                               "(opt-in, marked in the results)"),
        "accel_range_mps2": Field(float, "m/s^2", 0, 1e4, default=0.0, doc="full scale; samples at it are "
                                  "clipped and skipped (0: unknown)"),
        "gyro_range_radps": Field(float, "rad/s", 0, 1e3, default=0.0, doc="full scale (0: unknown)"),
        "max_gap_s": Field(float, "s", 0.001, 3600, default=0.1, doc="longer IMU gaps reset the position, "
                           "velocity and heading covariance (fixes inside them dropped); shorter ones are bridged"),
    },
    "gnss": {
        "file": Field(str, "-", default=REQ, doc="fixes: CSV, npy/npz array, NMEA or UBX log"),
        "format": Field(str, "-", default="csv", choices=FORMATS + ("nmea", "ubx")),
        "array": Field(str, "-", default="", doc="npz: the array inside (empty: the only one)"),
        "delimiter": Field(str, "-", default=","),
        "time_column": Field(Column, "-", default=0, doc="time in `time_base`"),
        "time_base": Field(str, "-", default="unix", choices=UNIX_BASES, doc="unix, gps_week_tow or gps_seconds"),
        **WEEK_KEYS,
        "time_unit": Field(str, "-", default="s", choices=tuple(TIME_UNITS)),
        "lat_column": Field(Column, "-", default=1, doc="deg"),
        "lon_column": Field(Column, "-", default=2, doc="deg"),
        "height_column": Field(Column, "-", default=3, doc="m"),
        "sigma_columns": Field(list, "-", default=[], doc="per-fix 1-sigma E N U columns (m), if the receiver "
                               "gives them"),
        "sigma_m": Field(list, "m", default=[1.5, 1.5, 3.0], doc="1-sigma E N U without sigma columns"),
        "sigma_scale": Field((float, str), "-", default=1.0, doc="multiplies every fix sigma; 'auto': one "
                             "rescale per axis by sqrt(mean fix NIS) of a first pass, clamped, none if it diverged"),
        "height_datum": Field(str, "-", default="ellipsoid", choices=("ellipsoid", "msl"),
                              doc="heights of the fix file: WGS84 ellipsoidal, or above mean sea level (msl: "
                              "ellipsoidal = msl + geoid_separation_m); NMEA/UBX logs give ellipsoidal"),
        "geoid_separation_m": Field(float, "m", -120, 90, default=0.0, doc="geoid height N above the ellipsoid at "
                                    "the site, for msl heights (fixes and reference)"),
        "rate_hz": Field(float, "Hz", 0, 100, default=0.0, doc="use at most this many fixes per second (0: all)"),
        "time_offset_s": Field((float, str), "s", default=0.0,
                               doc="fix latency on the IMU's time axis: a fix tagged t is the antenna at t - "
                               "time_offset_s (a known value shifts the tags); 'estimate': a filter state "
                               "(prior time_offset_sigma_s, random walk time_offset_rw), reported with its sigma"),
        "time_offset_sigma_s": Field(float, "s", 1e-4, 10, default=LATENCY_PRIOR_SIGMA_S, doc="prior 1-sigma of the estimated "
                                     "latency (around time_offset_prior_s)"),
        "time_offset_prior_s": Field(float, "s", -10, 10, default=0.0, doc="prior mean of the estimated latency"),
        "time_offset_rw": Field(float, "s/sqrt(s)", 0, 1, default=LATENCY_RANDOM_WALK, doc="random walk of the estimated latency "
                                "(0: constant)"),
        "velocity_columns": Field(list, "-", default=[], doc="GNSS velocity E N U columns (m/s), if the file has "
                                  "them; used as a measurement in modes with 'vel'"),
        "velocity_sigma_columns": Field(list, "-", default=[], doc="per-fix 1-sigma E N U velocity columns (m/s)"),
        "velocity_sigma_mps": Field(list, "m/s", default=[0.1, 0.1, 0.2], doc="1-sigma E N U velocity without "
                                    "sigma columns"),
        "lever_arm_m": Field(list, "m", default=[0.0, 0.0, 0.0], doc="IMU -> antenna, in `lever_arm_frame`"),
        "lever_arm_frame": Field(str, "-", default="FRD", choices=BODY_FRAMES),
    },
    "reference": {
        "file": Field(str, "-", default="", doc="reference trajectory (CSV, npy/npz or RTKLIB .pos); empty: none"),
        "format": Field(str, "-", default="csv", choices=FORMATS + ("pos",)),
        "array": Field(str, "-", default="", doc="npz: the array inside (empty: the only one)"),
        "delimiter": Field(str, "-", default=","),
        "crs": Field(str, "-", default="llh", doc="llh (deg, deg, m), ecef (m), or EPSG:code (x, y, h)"),
        "time_column": Field(Column, "-", default=0, doc="time in `time_base`"),
        "time_base": Field(str, "-", default="unix", choices=UNIX_BASES, doc="unix, gps_week_tow or gps_seconds"),
        **WEEK_KEYS,
        "time_unit": Field(str, "-", default="s", choices=tuple(TIME_UNITS)),
        "height_datum": Field(str, "-", default="ellipsoid", choices=("ellipsoid", "msl"),
                              doc="heights of an llh or EPSG reference (msl: plus [gnss] geoid_separation_m)"),
        "position_columns": Field(list, "-", default=[1, 2, 3]),
        "quaternion_columns": Field(list, "-", default=[], doc="4 columns of a body -> `attitude` frame quaternion "
                                    "in `quaternion_order`; its yaw (body x) is scored"),
        "attitude": Field(str, "-", default="quat_enu", choices=ATTITUDES, doc="quat_enu / quat_ned (local level, "
                          "CRS grid), quat_ecef, or euler_deg (euler_columns: roll pitch yaw, yaw from North clockwise)"),
        "quaternion_order": Field(str, "-", default="xyzw", choices=("xyzw", "wxyz")),
        "euler_columns": Field(list, "-", default=[], doc="attitude = euler_deg: roll, pitch, yaw columns (deg)"),
    },
    "filter": {
        "modes": Field(list, "-", default=list(MODES), doc=", ".join(MODES)),
        "imu_noise": Field(str, "-", default="standstill", choices=("standstill", "tactical", "wt901"),
                           doc="white noise measured at the first standstill, or a profile"),
        "bias_profile": Field(str, "-", default="wt901", choices=("tactical", "wt901"),
                              doc="bias sigmas and random walks"),
        "gate_nis": Field(float, "-", 0, 1e6, default=10.83, doc="chi2(1) 99.9 %; 0 disables"),
        "lockout_fixes": Field(int, "-", 0, 1000, default=5, doc="after this many consecutive fix epochs with a "
                               "gated fix, reset the position and velocity covariance (0: never)"),
        "velocity_sigma_mps": Field(float, "m/s", 1e-3, 100, default=0.3),
        "roll_pitch_sigma_deg": Field(float, "deg", 1e-3, 90, default=2.0),
        "output_rate_hz": Field(float, "Hz", 0.1, 1000, default=10.0, doc="trajectory file rate"),
    },
    "alignment": {
        "yaw_deg": Field((float, str), "deg", default="gnss", doc="'gnss': course of the GNSS velocity once "
                         "moving; or a given yaw from East towards North"),
        "speed_mps": Field(float, "m/s", 0.01, 100, default=0.2, doc="moving above this GNSS speed"),
        "window_s": Field(float, "s", 0.1, 60, default=2.0, doc="GNSS velocity window (course, speed)"),
        "yaw_sigma_deg": Field(float, "deg", 0.1, 180, default=15.0),
        "static_max_s": Field(float, "s", 0, 600, default=5.0, doc="longest initial standstill used for "
                              "leveling, gyro bias and noise"),
    },
    "constraints": {
        "nhc_rate_hz": Field(float, "Hz", 0.1, 200, default=10.0),
        "nhc_sigma_mps": Field(list, "m/s", default=[0.1, 0.1], doc="lateral, vertical"),
        "zupt_rate_hz": Field(float, "Hz", 0.1, 200, default=10.0),
        "zupt_sigma_mps": Field(float, "m/s", 1e-4, 10, default=0.02),
        "standstill_window_s": Field(float, "s", 0.05, 60, default=0.5),
        "standstill_accel_std_mps2": Field(float, "m/s^2", 0, 10, default=0.05),
        "standstill_gyro_std_radps": Field(float, "rad/s", 0, 10, default=0.02),
    },
    "scoring": {
        "outage_starts_s": Field((list, str), "s", default="auto",
                                 doc="seconds from the first GNSS fix; 'auto': 5 outages at 20, 35, 50, 65 and 80 % of "
                                 "the IMU/GNSS overlap; [] none"),
        "outage_length_s": Field((float, str), "s", default="auto",
                                 doc="'auto': 30 s, or 10 % of the overlap when that is shorter"),
        "yaw_skip_s": Field((float, str), "s", default="auto", doc="yaw RMSE from this time on; 'auto': 60 s, or "
                            "15 % of the overlap when that is shorter"),
    },
}


def _local_sections() -> None:
    """A section per local sensor of the registry (`[baro]`, `[mag]`): its file and columns, the
    sigma key and the parameters it declares (the same keys as in a scenario's section)."""
    import math as _math

    for token in model.LOCAL_SENSORS:
        obs = [o for o in model.OBSERVABLES if o.token == token]
        n = obs[0].noise
        SCHEMA[token] = {
            "file": Field(str, "-", default="", doc=f"{token} samples (CSV); empty: none"),
            "delimiter": Field(str, "-", default=","),
            "time_column": Field(Column, "-", default=0, doc="time in the IMU's time base; the IMU's time offset "
                                 "applies"),
            "time_unit": Field(str, "-", default="s", choices=tuple(TIME_UNITS)),
            "columns": Field(list, "-", default=[], doc="one column per observable: " + ", ".join(
                f"{o.suffix} ({o.unit})" for o in obs)),
            n.key: Field(float, n.key.rsplit("_", 1)[-1].replace("mps", "m/s"), n.lo, n.hi, default=n.default,
                         doc=n.doc),
        }
        for q in model.PARAMS:
            section, _, key = q.scenario.partition(".")
            if section == token:
                value = _math.degrees(q.default) if key.endswith("_deg") else q.default
                SCHEMA[token][key] = Field(float, key.rsplit("_", 1)[-1], q.lo, q.hi, default=value, doc=q.doc)


_local_sections()


@dataclass
class DatasetSpec:
    """A validated dataset description: `sections[name][key]` with SI values (angles in rad
    where the key says deg in the file), file paths resolved, and `source` (the TOML)."""

    name: str
    description: str
    source: str
    data_dir: Path
    sections: dict[str, dict[str, Any]] = field(default_factory=dict)
    shared: bool = False     # data_dir is the shared public data ({shared})

    def __getitem__(self, section: str) -> dict[str, Any]:
        return self.sections[section]

    def where(self, section: str, key: str) -> str:
        return where_key(self.source, section, key)


def shared_data_candidates() -> list[Path]:
    """Where `{shared}` is looked for, in order: ../shared/data beside the source tree this code
    runs from (a checkout or an editable install), then beside the current folder and its
    parents (a `pip install .` copies the package away from the checkout it came from)."""
    here = Path(__file__).resolve().parents[2].parent / "shared" / "data"
    cwd = Path.cwd().resolve()
    return [here] + [folder.parent / "shared" / "data" for folder in (cwd, *cwd.parents) if folder.parent != folder]


def shared_data_dir() -> Path:
    """$LEONAV_SHARED_DATA, else the first of `shared_data_candidates()` that exists (else the
    first candidate, so the message names where it was expected)."""
    env = os.environ.get("LEONAV_SHARED_DATA")
    if env:
        return Path(env)
    candidates = shared_data_candidates()
    return next((c for c in candidates if c.is_dir()), candidates[0])


def parse_axes(text: str, where: str) -> list[tuple[int, float]]:
    """'-y,x,z' -> [(sensor axis index, sign)] per vehicle axis; a UserInputError unless each
    sensor axis appears once."""
    if not AXES.match(text):
        raise UserInputError(f"{where} = {text!r}: expected three signed sensor axes such as '-y,x,z'")
    out = []
    for part in text.replace(" ", "").split(","):
        sign = -1.0 if part.startswith("-") else 1.0
        out.append(("xyz".index(part[-1]), sign))
    if len({a for a, _ in out}) != 3:
        raise UserInputError(f"{where} = {text!r}: expected each of x, y, z once")
    return out


def spec_from_dict(data: dict[str, Any], source: str = "<dict>", base_dir: Path | None = None) -> DatasetSpec:
    """Validate a parsed dataset TOML mapping (module doc)."""
    values = check_tables(source, data, SCHEMA, REQ, optional_sections=("reference", *model.LOCAL_SENSORS))
    _finish(values, source)
    base = base_dir or Path.cwd()
    text = values["data"]["dir"].replace("{shared}", str(shared_data_dir()))
    data_dir = Path(text) if Path(text).is_absolute() else base / text
    return DatasetSpec(values[""]["name"], values[""]["description"], source, data_dir, values,
                       "{shared}" in values["data"]["dir"])


def _finish(v: dict[str, dict[str, Any]], source: str) -> None:
    """Lists, choices and conversions the per-key check cannot do."""
    imu, gnss = v["imu"], v["gnss"]
    imu["axis_map"] = parse_axes(imu["axes"], where_key(source, "imu", "axes"))
    for sec, key in (("imu", "time_offset_s"), ("gnss", "time_offset_s"), ("gnss", "sigma_scale"),
                     ("alignment", "yaw_deg")):
        val = v[sec][key]
        words = {("imu", "time_offset_s"): ("calibrate", "calibrate_reference"), ("gnss", "time_offset_s"): ("estimate",),
                 ("gnss", "sigma_scale"): ("auto",), ("alignment", "yaw_deg"): ("gnss",)}[(sec, key)]
        if isinstance(val, str) and val not in words:
            raise UserInputError(f"{where_key(source, sec, key)} = {show_value(val)}: expected a number or "
                                 f"{' or '.join(repr(w) for w in words)}")
    if isinstance(gnss["sigma_scale"], float) and not 0.01 <= gnss["sigma_scale"] <= 100:
        raise UserInputError(f"{where_key(source, 'gnss', 'sigma_scale')}: expected 0.01..100 or 'auto'")
    gnss["sigma_columns"] = _columns(source, "gnss", "sigma_columns", gnss["sigma_columns"], None)
    if len(gnss["sigma_columns"]) not in (0, 3):
        raise UserInputError(f"{where_key(source, 'gnss', 'sigma_columns')}: expected 3 columns (E N U) or none")
    if not isinstance(gnss["time_offset_s"], str) and abs(gnss["time_offset_s"]) > 10:
        raise UserInputError(f"{where_key(source, 'gnss', 'time_offset_s')}: expected a latency within +-10 s or "
                             "'estimate' (a clock offset of the IMU is [imu] time_offset_s)")
    for key in ("velocity_columns", "velocity_sigma_columns"):
        gnss[key] = _columns(source, "gnss", key, gnss[key], None)
        if len(gnss[key]) not in (0, 3):
            raise UserInputError(f"{where_key(source, 'gnss', key)}: expected 3 columns (E N U, m/s) or none")
    if gnss["velocity_sigma_columns"] and not gnss["velocity_columns"]:
        raise UserInputError(f"{where_key(source, 'gnss', 'velocity_sigma_columns')}: given without "
                             "velocity_columns: expected both or neither")
    gnss["velocity_sigma_mps"] = check_numbers(source, "gnss", "velocity_sigma_mps", gnss["velocity_sigma_mps"], 3,
                                               "m/s", limit=100.0)
    if min(gnss["velocity_sigma_mps"]) <= 0:
        raise UserInputError(f"{where_key(source, 'gnss', 'velocity_sigma_mps')}: expected 3 numbers > 0 (m/s)")
    gnss["sigma_m"] = check_numbers(source, "gnss", "sigma_m", gnss["sigma_m"], 3, "m", limit=1e4)
    if min(gnss["sigma_m"]) <= 0:
        raise UserInputError(f"{where_key(source, 'gnss', 'sigma_m')}: expected 3 numbers > 0 (m)")
    arm = check_numbers(source, "gnss", "lever_arm_m", gnss["lever_arm_m"], 3, "m", limit=100.0)
    gnss["lever_arm_flu_m"] = arm if gnss["lever_arm_frame"] == "FLU" else [arm[0], -arm[1], -arm[2]]
    finish_sources(v, source)   # columns, formats, time bases, attitude of [imu] [gnss] [reference]
    modes = v["filter"]["modes"]
    if not modes or not all(isinstance(m, str) for m in modes):
        raise UserInputError(f"{where_key(source, 'filter', 'modes')} = {show_value(modes)}: expected a non-empty "
                             f"list of modes, e.g. {', '.join(MODES)}")
    v["filter"]["modes"] = model.check_modes(modes, dataset_observable, f"{where_key(source, 'filter', 'modes')}:")
    used = {t for m in v["filter"]["modes"] for t in dataset_mode(m).local_sensors}
    for token in model.LOCAL_SENSORS:
        sec = v[token]
        k = len(model.stream_observables(token))
        sec["columns"] = _columns(source, token, "columns", sec["columns"], k if sec["file"] else None)
        if token in used and not sec["file"]:
            raise UserInputError(f"{where_key(source, token, 'file')}: missing: a mode uses {token} "
                                 f"({', '.join(m for m in v['filter']['modes'] if token in m.split('+'))})")
        noise = model.stream_observables(token)[0].noise
        sec["sigma_si"] = math.radians(sec[noise.key]) if noise.key.endswith("_deg") else sec[noise.key]
    v["filter"]["roll_pitch_sigma_rad"] = math.radians(v["filter"]["roll_pitch_sigma_deg"])
    al = v["alignment"]
    if not isinstance(al["yaw_deg"], str) and not -360 <= al["yaw_deg"] <= 360:
        raise UserInputError(f"{where_key(source, 'alignment', 'yaw_deg')}: expected deg in [-360, 360] or 'gnss'")
    al["yaw_rad"] = None if isinstance(al["yaw_deg"], str) else math.radians(al["yaw_deg"])
    al["yaw_sigma_rad"] = math.radians(al["yaw_sigma_deg"])
    con = v["constraints"]
    con["nhc_sigma_mps"] = check_numbers(source, "constraints", "nhc_sigma_mps", con["nhc_sigma_mps"], 2, "m/s", 100.0)
    if min(con["nhc_sigma_mps"]) <= 0:
        raise UserInputError(f"{where_key(source, 'constraints', 'nhc_sigma_mps')}: expected 2 numbers > 0 (m/s)")
    sc = v["scoring"]
    for key, limit in (("outage_length_s", 3600.0), ("yaw_skip_s", 3600.0)):
        val = sc[key]
        if isinstance(val, str) and val != "auto" or not isinstance(val, str) and not 0 <= val <= limit:
            raise UserInputError(f"{where_key(source, 'scoring', key)} = {show_value(val)}: expected 'auto' or "
                                 f"seconds in [0, {limit:g}]")
    if sc["outage_length_s"] == 0:
        raise UserInputError(f"{where_key(source, 'scoring', 'outage_length_s')}: expected a length > 0 s or 'auto'")
    if isinstance(sc["outage_starts_s"], str):
        if sc["outage_starts_s"] != "auto":
            raise UserInputError(f"{where_key(source, 'scoring', 'outage_starts_s')} = "
                                 f"{show_value(sc['outage_starts_s'])}: expected a list of seconds or 'auto'")
    else:
        sc["outage_starts_s"] = check_numbers(source, "scoring", "outage_starts_s", sc["outage_starts_s"], None, "s",
                                              1e6)


def load_spec(path: str | Path) -> DatasetSpec:
    """Load and validate a dataset TOML file; a bare name like `cpet_run3` picks a shipped one
    (leonav_runtime/dataset/descriptions/)."""
    path = Path(path)
    shipped = Path(__file__).resolve().parent / "descriptions"
    if not path.exists() and (shipped / f"{path.stem}.toml").exists() and path.parent == Path("."):
        path = shipped / f"{path.stem}.toml"
    if not path.is_file():
        names = ", ".join(sorted(p.stem for p in shipped.glob("*.toml")))
        raise UserInputError(f"{path}: dataset file not found (shipped: {names})")
    data = read_toml_file(path, "dataset description", MAX_FILE_BYTES)
    return spec_from_dict(data, source=str(path), base_dir=path.parent)
