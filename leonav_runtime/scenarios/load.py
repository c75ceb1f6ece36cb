"""Scenarios: TOML files in human units, converted to SI once and validated.

A scenario file names its unit in every key (`lat_deg`, `duration_s`, `rate_hz`) and carries
a unit comment on every line. `load_scenario(path)` checks every field against the schema
below (type, unit, range, allowed values), rejects unknown keys (typos), and returns a
`Scenario` whose fields are SI (rad, m, s, Hz). Errors name the file, the field, the value
and what was expected.

Limits, checked before anything is allocated: a scenario file of at most 1 MB; measurement
rates that divide the IMU rate and give an epoch within the run; manoeuvres within 100 m/s^2,
180 deg/s and 0..400 m/s; the memory a run needs at most LEONAV_MAX_MEMORY_MB (`run_size`).

Satellite-selection rules (`starlink.selection`): `"highest-elevation"`: at every Starlink
epoch the N satellites above the mask with the highest elevation are used, so over a long
run the set follows the sky as satellites rise and set. `"random"`: every satellite gets a
random priority drawn once from `starlink.selection_seed`, and at every epoch the N visible
satellites of highest priority are used (a receiver that tracks an arbitrary subset and keeps
it while it stays above the mask; all trials of a run share the draw). Asking for more
satellites than are above the mask at some epoch is an error that names the count
available, never a silent cap.
"""
from __future__ import annotations

import datetime as _dt
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from leonav_runtime.scenarios import run_size
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.common.toml_file import read_toml_file
from leonav_runtime.common.utc import parse_utc
from leonav_runtime.core import model
from leonav_runtime.core.model import LOCAL_SENSORS
from leonav_runtime.scenarios.schema import (IMU_PROFILES, MODES, SCHEMA, SELECTION_RULES,  # noqa: F401
                                             TRAJECTORY_KINDS, Field, _REQUIRED, mode_of)

BUILTIN_DIR = Path(__file__).resolve().parent   # the built-in scenario files sit beside this module
MAX_FILE_BYTES = 1_000_000
MAX_ACCEL_MPS2, MAX_TURN_DEG_S, MAX_COUNT = 100.0, 180.0, 10_000
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._+-]{0,63}")


@dataclass
class Scenario:
    """A validated scenario in SI units (rad, m, s, Hz). `source` is the file it came from."""

    name: str
    description: str
    lat_rad: float
    lon_rad: float
    alt_m: float
    epoch_utc: _dt.datetime
    duration_s: float
    trajectory: dict[str, Any]
    imu_profile: str
    imu_rate_hz: float
    gps: dict[str, Any]
    starlink: dict[str, Any]
    element_source: str
    element_files: list[Path]
    filter: dict[str, Any]
    trials: int
    seed: int
    modes: list[str]
    source: str = "<defaults>"
    raw: dict[str, Any] = field(default_factory=dict, repr=False)
    realism: dict[str, dict[str, Any]] = field(default_factory=dict)  # "ephemeris", "imu": SI, see realism.py
    local: dict[str, dict[str, Any]] = field(default_factory=dict)    # each local sensor's section (rate_hz, sigma)
    params: dict[str, float] = field(default_factory=dict)            # registry parameters a scenario key sets (SI)


def where_key(source: str, section: str, key: str) -> str:
    """'file: [section] key', the prefix of every description error."""
    return f"{source}: [{section}] {key}" if section else f"{source}: {key}"


def show_value(value: Any) -> str:
    """A value as an error message quotes it (repr, at most 80 characters)."""
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _finite(value: Any) -> bool:
    try:
        return math.isfinite(value)
    except OverflowError:   # an integer beyond any float
        return False


def check_value(source: str, section: str, key: str, spec: Field, value: Any) -> Any:
    """`value` checked against its Field (type, range, choices), ints widened to float where
    allowed, else a UserInputError naming the key; scenarios and dataset descriptions share it."""
    where, given = where_key(source, section, key), value
    kinds = spec.kind if isinstance(spec.kind, tuple) else (spec.kind,)
    if float in kinds and isinstance(value, int) and not isinstance(value, bool):
        value = float(value) if _finite(value) else math.inf
    if not isinstance(value, kinds) or (isinstance(value, bool) and bool not in kinds):
        names = " or ".join(k.__name__ for k in kinds)
        raise UserInputError(f"{where} = {show_value(value)}: expected a {names} in {spec.unit}")
    if isinstance(value, (int, float)):
        if isinstance(given, float) and not _finite(given):   # NaN passes every comparison
            raise UserInputError(f"{where} = {show_value(value)}: expected a finite number in {spec.unit}")
        if (spec.lo is not None and value < spec.lo) or (spec.hi is not None and value > spec.hi):
            raise UserInputError(f"{where} = {show_value(given if isinstance(given, int) else value)}: expected "
                                 f"{spec.unit} in [{spec.lo}, {spec.hi}]")
    if spec.choices is not None and value not in spec.choices:
        raise UserInputError(f"{where} = {show_value(value)}: expected one of {', '.join(spec.choices)}")
    return value


def check_numbers(source: str, section: str, key: str, value: Any, length: int | None,
                  unit: str, limit: float = math.inf) -> list[float]:
    """`value` as a list of `length` finite numbers (any length if None) within +-limit, else a
    UserInputError naming the key and the unit."""
    where = where_key(source, section, key)
    ok = isinstance(value, list) and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and _finite(v) and abs(v) <= limit for v in value
    )
    if not ok or (length is not None and len(value) != length):
        n = f"{length} " if length is not None else ""
        within = f" within +-{limit:g}" if limit < math.inf else ""
        raise UserInputError(f"{where} = {show_value(value)}: expected a list of {n}numbers in {unit}{within}")
    return [float(v) for v in value]


def check_tables(source: str, data: dict[str, Any], schema: dict[str, dict[str, Field]], required: Any,
                 optional_sections: tuple[str, ...] = ()) -> dict[str, dict[str, Any]]:
    """Validate a parsed TOML mapping against `schema` ({section: {key: Field}}, "" the top
    level): unknown sections and keys, tables where tables belong, every value
    (`check_value`); defaults filled in. A key whose default is `required` must be given,
    unless its section is one of `optional_sections` and absent altogether."""
    for key in data:
        if key not in schema and key not in schema.get("", {}):
            raise UserInputError(f"{source}: unknown section or key {key!r}; expected one of "
                                 f"{', '.join(sorted({k for k in schema if k} | set(schema.get('', {}))))}")
    values: dict[str, dict[str, Any]] = {}
    for section, fields in schema.items():
        given = data if section == "" else data.get(section, {})
        if section and not isinstance(given, dict):
            raise UserInputError(f"{source}: [{section}] must be a table, got {show_value(given)}")
        if section:
            unknown = set(given) - set(fields)
            if unknown:
                raise UserInputError(f"{source}: [{section}] unknown key {show_value(sorted(unknown)[0])}; "
                                     f"expected one of {', '.join(fields)}")
        skip_required = section in optional_sections and section not in data
        out: dict[str, Any] = {}
        for key, spec in fields.items():
            if key in given:
                out[key] = check_value(source, section, key, spec, given[key])
            elif spec.default is required and not skip_required:
                raise UserInputError(f"{where_key(source, section, key)} is missing: required ({spec.unit})")
            else:
                out[key] = spec.default
        values[section] = out
    return values


def scenario_from_dict(data: dict[str, Any], source: str = "<dict>",
                       base_dir: Path | None = None) -> Scenario:
    """Validate a parsed TOML mapping and convert it to an SI `Scenario`."""
    values = check_tables(source, data, SCHEMA, _REQUIRED)

    traj = dict(values["trajectory"])
    att = check_numbers(source, "trajectory", "attitude_deg", traj["attitude_deg"], 3, "deg", limit=360.0)
    traj["attitude_rad"] = [math.radians(a) for a in att]
    maneuvers, t_end, speed = [], 0.0, traj["speed_mps"]
    for i, m in enumerate(traj["maneuvers"]):
        row = check_numbers(source, "trajectory", f"maneuvers[{i}]", m, 3,
                       "[duration_s, acceleration_mps2, turn_rate_deg_s]")
        where = f"{source}: [trajectory] maneuvers[{i}]"
        for what, value, lo, hi, unit in (("duration", row[0], 1e-3, 86400, "s"),
                                          ("acceleration", row[1], -MAX_ACCEL_MPS2, MAX_ACCEL_MPS2, "m/s^2"),
                                          ("turn rate", row[2], -MAX_TURN_DEG_S, MAX_TURN_DEG_S, "deg/s")):
            if not lo <= value <= hi:
                raise UserInputError(f"{where} {what} {value:g} {unit}: expected {lo:g}..{hi:g} {unit}")
        t_end, speed = t_end + row[0], speed + row[0] * row[1]
        if not 0 <= speed <= SCHEMA["trajectory"]["speed_mps"].hi:
            raise UserInputError(f"{source}: [trajectory] maneuvers make the speed {speed:g} m/s at {t_end:g} s: "
                                 f"expected 0..{SCHEMA['trajectory']['speed_mps'].hi:g} m/s")
        maneuvers.append((row[0], row[1], math.radians(row[2])))
    traj["maneuvers"] = maneuvers
    traj["roll_amplitude_rad"] = math.radians(traj.pop("roll_amplitude_deg"))
    traj["pitch_amplitude_rad"] = math.radians(traj.pop("pitch_amplitude_deg"))
    del traj["attitude_deg"]

    duration = values["time"]["duration_s"]
    gps = dict(values["gps"])
    outages = []
    for i, w in enumerate(gps.pop("outages_s")):
        a, b = check_numbers(source, "gps", f"outages_s[{i}]", w, 2, "[start_s, end_s]")
        if not 0 <= a < b <= duration:
            raise UserInputError(f"{source}: [gps] outages_s[{i}] = {show_value(w)}: expected 0 <= start < end <= "
                                 f"duration ({duration} s)")
        outages.append((a, b))
    gps["outages"] = outages
    gps["elevation_mask_rad"] = math.radians(gps.pop("elevation_mask_deg"))

    star = dict(values["starlink"])
    counts = star["counts"]
    if not counts or not all(isinstance(c, int) and not isinstance(c, bool) and 1 <= c <= MAX_COUNT for c in counts):
        raise UserInputError(f"{source}: [starlink] counts = {show_value(counts)}: expected a non-empty list of "
                             f"integers >= 1 (at most {MAX_COUNT})")
    star["counts"] = sorted(set(counts))  # ascending: min/max and curves read it in order
    star["elevation_mask_rad"] = math.radians(star.pop("elevation_mask_deg"))

    files = values["elements"]["files"]
    if not all(isinstance(f, str) and f and "\0" not in f for f in files):
        raise UserInputError(f"{source}: [elements] files = {show_value(files)}: expected a list of paths")
    base = base_dir or Path.cwd()
    element_files = [(base / f) if not Path(f).is_absolute() else Path(f) for f in files]
    if values["elements"]["source"] == "files" and not element_files:
        raise UserInputError(f"{source}: [elements] source = 'files' but files is empty")

    modes = values["monte_carlo"]["modes"]
    if not isinstance(modes, list) or not modes or not all(isinstance(m, str) for m in modes):
        raise UserInputError(f"{source}: [monte_carlo] modes = {show_value(modes)}: expected a non-empty list of "
                             f"mode names, e.g. {', '.join(MODES)}")
    modes = list(dict.fromkeys(modes))  # keep the given order, drop repeats
    for m in modes:
        mode_of(m, f"{source}: [monte_carlo] modes:")
    filt = dict(values["filter"])
    filt["initial_attitude_sigma_rad"] = math.radians(filt.pop("initial_attitude_sigma_deg"))
    if filt["covariance_interval_s"] > 0 and values["ephemeris_error"]["compensate"] == "states":
        raise UserInputError(f"{source}: [filter] covariance_interval_s = {filt['covariance_interval_s']:g}: the "
                             "orbit-offset states ([ephemeris_error] compensate = 'states') propagate the covariance "
                             "at every IMU sample; expected covariance_interval_s = 0 with them")
    if not NAME.fullmatch(values[""]["name"]):   # it names output folders: never a path
        raise UserInputError(f"{source}: name = {show_value(values['']['name'])}: "
                             "expected 1-64 letters, digits, '.', '_', "
                             "'+' or '-' (it names the results folder), starting with a letter or digit")
    used = {section for m in modes for section in (*mode_of(m).constellations, *mode_of(m).local_sensors)}
    imu_hz = values["imu"]["rate_hz"]
    for section in sorted(used):
        rate = values[section]["rate_hz"]
        if abs(imu_hz / rate - round(imu_hz / rate)) > 1e-9:
            raise UserInputError(f"{source}: [{section}] rate_hz = {rate:g}: measurements are tagged on IMU samples, "
                                 f"so it must divide the IMU rate {imu_hz:g} Hz")
        if round(imu_hz / rate) > round(duration * imu_hz):
            raise UserInputError(f"{source}: [{section}] rate_hz = {rate:g}: one epoch every {1 / rate:g} s, none "
                                 f"within duration_s = {duration:g} s; expected a rate >= {1 / duration:g} Hz")

    return Scenario(
        realism=_realism(source, values["ephemeris_error"], values["imu_errors"], base, values["front_end"],
                         values["base"]),
        name=values[""]["name"],
        description=values[""]["description"],
        lat_rad=math.radians(values["site"]["lat_deg"]),
        lon_rad=math.radians(values["site"]["lon_deg"]),
        alt_m=values["site"]["alt_m"],
        epoch_utc=parse_utc(values["time"]["epoch"], f"{source}: [time] epoch", require_zone=True),
        duration_s=duration,
        trajectory=traj,
        imu_profile=values["imu"]["profile"],
        imu_rate_hz=values["imu"]["rate_hz"],
        gps=gps,
        starlink=star,
        element_source=values["elements"]["source"],
        element_files=element_files,
        filter=filt,
        trials=values["monte_carlo"]["trials"],
        seed=values["monte_carlo"]["seed"],
        modes=list(modes),
        local={token: dict(values[token]) for token in LOCAL_SENSORS},
        params=_scenario_params(values),
        source=source,
        raw=data,
    )


def _scenario_params(values: dict[str, dict[str, Any]]) -> dict[str, float]:
    """The registry parameters set by scenario keys, SI (a `_deg` key converts to rad)."""
    out = {}
    for q in model.PARAMS:
        if q.scenario:
            section, _, key = q.scenario.partition(".")
            value = values[section][key]
            out[q.name] = math.radians(value) if key.endswith("_deg") else float(value)
    return out


def _realism(source: str, eph: dict[str, Any], imu: dict[str, Any], base: Path | None = None,
             front_end: dict[str, Any] | None = None, station: dict[str, Any] | None = None
             ) -> dict[str, dict[str, Any]]:
    """The realism sections in SI: sigmas (m), rad, m/s^2 and rad/s per degC, rates; the
    operator-ephemeris folder as a path from `base` (the scenario file's folder)."""
    eph = dict(eph)
    folder = eph.get("operator_folder", "")
    if folder:
        if eph["compensate"] != "consider":
            raise UserInputError(f"{source}: [ephemeris_error] operator_folder = {show_value(folder)} is used only by "
                                 f"compensate = 'consider' (found {show_value(eph['compensate'])})")
        path = Path(folder) if Path(folder).is_absolute() else (base or Path.cwd()) / folder
        if not path.is_dir():
            raise UserInputError(f"{source}: [ephemeris_error] operator_folder = {show_value(folder)}: {path} is not "
                                 "a folder (expected MANIFEST.txt and MEME_*.txt operator ephemerides)")
        eph["operator_folder"] = str(path)
    for key in ("starlink_sigma_rac_m", "gps_sigma_rac_m"):
        eph[key] = check_numbers(source, "ephemeris_error", key, eph[key], 3, "m", limit=1e7)
        if min(eph[key]) < 0:
            raise UserInputError(f"{source}: [ephemeris_error] {key} = {show_value(eph[key])}: expected sigmas >= 0 m")
    if eph["compensate"] == "states" and min(eph["starlink_sigma_rac_m"]) <= 0:
        raise UserInputError(f"{source}: [ephemeris_error] compensate = 'states' takes the Starlink sigmas as the "
                             f"offsets' prior: starlink_sigma_rac_m = {show_value(eph['starlink_sigma_rac_m'])}, "
                             "expected three sigmas > 0 m")
    bad = [c for c in eph["apply_to"] if c not in ("starlink", "gps")] if isinstance(eph["apply_to"], list) else [1]
    if bad:
        raise UserInputError(f"{source}: [ephemeris_error] apply_to = "
                             f"{show_value(eph['apply_to'])}: expected a list of "
                             "starlink, gps")
    g0 = 9.80665
    imu_si = {"enabled": imu["enabled"], "process_noise_inflation": imu["process_noise_inflation"],
              "accel_scale_factor": 1e-6 * imu["accel_scale_factor_ppm"],
              "gyro_scale_factor": 1e-6 * imu["gyro_scale_factor_ppm"],
              "misalignment_rad": 1e-3 * imu["misalignment_mrad"],
              "g_sensitivity_rad_s_per_mps2": math.radians(imu["g_sensitivity_deg_s_per_g"]) / g0,
              "temperature_rate_c_per_s": imu["temperature_rate_c_per_s"],
              "accel_bias_tempco_mps2_per_c": 1e-3 * g0 * imu["accel_bias_tempco_mg_per_c"],
              "gyro_bias_tempco_rad_s_per_c": math.radians(imu["gyro_bias_tempco_deg_s_per_c"])}
    out = {"ephemeris": eph, "imu": imu_si}
    if front_end is not None:
        lo, hi = check_numbers(source, "front_end", "cn0_dbhz", front_end["cn0_dbhz"], 2, "dB-Hz", limit=100.0)
        if not 0 < lo <= hi:
            raise UserInputError(f"{source}: [front_end] cn0_dbhz = {show_value(front_end['cn0_dbhz'])}: expected "
                                 "[at the mask, at the zenith] with 0 < the first <= the second")
        out["front_end"] = {**front_end, "cn0_dbhz": [lo, hi]}
    if station is not None:
        offset = check_numbers(source, "base", "offset_enu_m", station["offset_enu_m"], 3, "m", limit=1e6)
        if station["enabled"] and eph["compensate"] == "states":
            raise UserInputError(f"{source}: [base] enabled = true serves corrected orbits; [ephemeris_error] "
                                 "compensate = 'states' estimates the element orbits' offsets instead: use one "
                                 "(with [base], compensate = 'consider' or 'inflate-r')")
        if station["enabled"] and not eph["enabled"]:
            raise UserInputError(f"{source}: [base] enabled = true corrects the orbit error: it needs "
                                 "[ephemeris_error] enabled = true")
        out["base"] = {**station, "offset_enu_m": list(offset)}
    return out


def load_scenario(path: str | Path) -> Scenario:
    """Load and validate a scenario TOML file; a bare name like `paper` picks a built-in one."""
    path = Path(path)
    if not path.exists() and (BUILTIN_DIR / f"{path.name}.toml").exists():
        path = BUILTIN_DIR / f"{path.name}.toml"
    if not path.exists():
        builtins = ", ".join(sorted(p.stem for p in BUILTIN_DIR.glob("*.toml")))
        raise UserInputError(f"{path}: scenario file not found (built-in scenarios: {builtins})")
    data = read_toml_file(path, "scenario", MAX_FILE_BYTES)
    scn = scenario_from_dict(data, source=str(path), base_dir=path.parent)
    check_run_size(scn, trials=0, workers=1)   # what every command needs: the simulator and one trial
    return scn


def check_run_size(scn: Scenario, trials: int | None = None, workers: int | None = None) -> None:
    """`run_size.check_run_size` with this module's modes (trials None: the scenario's; workers None: all cores)."""
    run_size.check_run_size(scn, mode_of, SCHEMA["monte_carlo"]["trials"].hi, trials, workers)


def builtin_scenarios() -> list[str]:
    """Names of the scenarios shipped with leonav."""
    return sorted(p.stem for p in BUILTIN_DIR.glob("*.toml"))


def schema_markdown(local_sensors: bool = False) -> str:
    """The key reference of docs/scenarios.md, generated from SCHEMA (a test keeps them equal);
    the sections of local sensors (`[baro]`, ...: registry-made, one per sensor module) only with
    `local_sensors` (they are listed in leonav_runtime/gen/REGISTRY.md, which codegen writes)."""
    lines = []
    for section, fields in SCHEMA.items():
        if (section in LOCAL_SENSORS) != local_sensors and section:
            continue
        lines += [f"### {'top level' if not section else '[' + section + ']'}", "",
                  "| key | unit | range / choices | default | meaning |", "|---|---|---|---|---|"]
        for key, f in fields.items():
            rng = ", ".join(f.choices) if f.choices else (f"{f.lo:g} .. {f.hi:g}" if f.lo is not None else "")
            default = "required" if f.default is _REQUIRED else repr(f.default)
            lines.append(f"| `{key}` | {f.unit} | {rng} | {default} | {f.doc} |")
        lines.append("")
    return "\n".join(lines)
