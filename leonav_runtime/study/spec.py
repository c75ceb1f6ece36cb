"""Study files: a base scenario, fixed overrides and one or two varied scenario fields.

A study TOML names a base scenario (a built-in name or a file relative to the study), the
modes and the Starlink count every cell runs, `[set]` overrides and one or two `[[vary]]`
axes, each a dotted scenario key (`section.key`, as in the scenario file, in the file's
units) with its values. `--set key=value` on the command line adds to `[set]`. Every cell
(one combination of the varied values) is a complete scenario, validated by the scenario
schema; a bad key or value is reported with the study file and the key.

`starlink.counts` takes single counts as values (each cell then runs that count).
"""
from __future__ import annotations

import copy
import difflib
import itertools
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.study import BUILTIN_STUDY_DIR, shipped_studies
from leonav_runtime.common.toml_file import read_toml_file
from leonav_runtime.scenarios.load import NAME, SCHEMA, Scenario, load_scenario, scenario_from_dict

MAX_AXES, MAX_VALUES, MAX_CELLS = 2, 50, 400
STUDY_KEYS = ("name", "description", "scenario", "modes", "count", "trials", "set", "vary")
TRIALS = SCHEMA["monte_carlo"]["trials"]   # the bounds of trials per cell, as a scenario's


@dataclass(frozen=True)
class Axis:
    """One varied scenario field: dotted key, values (file units), axis label for figures."""

    key: str
    values: tuple[Any, ...]
    label: str


@dataclass
class Cell:
    """One point of the grid: the varied values (by key) and its validated scenario."""

    index: tuple[int, ...]
    values: dict[str, Any]
    scenario: Scenario
    count: int


@dataclass
class Study:
    """A validated study: its cells, axes, modes and trials per cell and mode."""

    name: str
    description: str
    source: str
    base: Scenario
    axes: list[Axis]
    modes: list[str]
    trials: int
    sets: dict[str, Any]
    cells: list[Cell] = field(default_factory=list)
    raw: dict[str, Any] = field(default_factory=dict, repr=False)


def _field_of(where: str, key: Any):
    """The schema Field of a dotted `section.key` (error names the key and near misses)."""
    known = [f"{s}.{k}" for s, fs in SCHEMA.items() if s for k in fs]
    if not isinstance(key, str) or key not in known:
        near = difflib.get_close_matches(str(key), known, n=3)
        hint = f"; did you mean {', '.join(near)}?" if near else f"; expected section.key, e.g. {known[0]}"
        raise UserInputError(f"{where}: unknown scenario key {key!r}{hint}")
    section, name = key.split(".", 1)
    return SCHEMA[section][name]


def apply_setting(raw: dict[str, Any], key: str, value: Any) -> None:
    """Set dotted `key` of a scenario mapping in place (a single count becomes [count])."""
    section, name = key.split(".", 1)
    spec = SCHEMA[section][name]
    if spec.kind is list and not isinstance(value, list) and key == "starlink.counts":
        value = [value]
    raw.setdefault(section, {})
    if not isinstance(raw[section], dict):
        raise UserInputError(f"[{section}] of the base scenario is not a table")
    raw[section][name] = value


def parse_set(text: str) -> tuple[str, Any]:
    """`key=value` of --set, the value read by the key's declared type: text for a text key (a date
    such as 2026-02-24T00:00:00Z as typed; quotes optional), a number for a number, true/false
    for a flag, a TOML list (or comma-separated numbers) for a list; else one line naming the key,
    what was given and what was expected."""
    key, sep, value = text.partition("=")
    key, value = key.strip(), value.strip()
    if not sep or not key or not value:
        raise UserInputError(f"--set {text!r}: expected key=value, e.g. starlink.doppler_rate_sigma_hz_s=0.3")
    spec = _field_of(f"--set {text!r}", key)
    return key, typed_value(key, value, spec.kind)


def typed_value(key: str, value: str, kind) -> Any:
    """A command-line text `value` as the schema type `kind` (`parse_set`)."""
    kinds = kind if isinstance(kind, tuple) else (kind,)
    try:
        toml_value = tomllib.loads(f"v = {value}")["v"]
    except tomllib.TOMLDecodeError:
        toml_value = None
    if isinstance(toml_value, bool) and bool in kinds:
        return toml_value
    if (float in kinds or int in kinds) and not isinstance(toml_value, bool):
        if isinstance(toml_value, (int, float)):
            return int(toml_value) if int in kinds and float not in kinds else toml_value
    if list in kinds:
        if isinstance(toml_value, list):
            return toml_value
        items = [v.strip() for v in value.split(",")]
        try:
            return [float(v) if any(c in v for c in ".eE") else int(v) for v in items]
        except ValueError:
            pass
    if str in kinds:
        return toml_value if isinstance(toml_value, str) else value
    names = {bool: "true or false", int: "an integer", float: "a number", list: "a list such as [1, 2]",
             str: "text"}
    raise UserInputError(f"--set {key}={value}: expected {' or '.join(names.get(k, k.__name__) for k in kinds)}")


def _value_key(v: Any) -> tuple:
    """What makes two grid values the same: numbers by value (1 == 1.0), bools apart from
    numbers (true != 1), anything else by its repr."""
    if isinstance(v, bool):
        return ("bool", v)
    if isinstance(v, (int, float)):
        return ("number", float(v))
    return ("other", repr(v))


def value_label(v: Any) -> str:
    """A grid value as cells, tables and figure ticks show it ("0.1", not "0.1000")."""
    return f"{v:g}" if isinstance(v, float) else str(v)


def expand_grid(axes: list[Axis]) -> list[tuple[tuple[int, ...], dict[str, Any]]]:
    """Every combination of the axes' values: (index per axis, {key: value}), first axis slowest."""
    out = []
    for idx in itertools.product(*(range(len(a.values)) for a in axes)):
        out.append((idx, {a.key: a.values[i] for a, i in zip(axes, idx)}))
    return out


def study_from_dict(data: dict[str, Any], source: str, base_dir: Path,
                    extra_sets: list[tuple[str, Any]] = ()) -> Study:
    """Validate a parsed study mapping; build and validate every cell's scenario."""
    if not isinstance(data, dict):
        raise UserInputError(f"{source}: expected a TOML table")
    unknown = sorted(set(data) - set(STUDY_KEYS))
    if unknown:
        raise UserInputError(f"{source}: unknown key {unknown[0]!r}; expected one of {', '.join(STUDY_KEYS)}")
    name = data.get("name", Path(source).stem)
    if not isinstance(name, str) or not NAME.fullmatch(name):
        raise UserInputError(f"{source}: name = {name!r}: expected 1-64 letters, digits, '.', '_', '+' or '-'")
    base_ref = data.get("scenario", "paper")
    if not isinstance(base_ref, str) or not base_ref:
        raise UserInputError(f"{source}: scenario = {base_ref!r}: expected a built-in name or a scenario file")
    ref = Path(base_ref)
    base = load_scenario(ref if ref.is_absolute() or not (base_dir / ref).exists() else base_dir / ref)

    sets: dict[str, Any] = {}
    table = data.get("set", {})
    if not isinstance(table, dict):
        raise UserInputError(f"{source}: [set] must be a table of \"section.key\" = value")
    for key, value in table.items():
        if isinstance(value, dict):   # an unquoted dotted key parses as a nested table
            value = {f"{key}.{k}": v for k, v in value.items()}
            for k, v in value.items():
                _field_of(f"{source}: [set]", k)
                sets[k] = v
            continue
        _field_of(f"{source}: [set]", key)
        sets[key] = value
    for key, value in extra_sets:
        sets[key] = value

    vary = data.get("vary", [])
    if not isinstance(vary, list) or not 1 <= len(vary) <= MAX_AXES:
        raise UserInputError(f"{source}: [[vary]]: expected one or two [[vary]] tables (key, values)")
    axes = []
    for i, ax in enumerate(vary):
        where = f"{source}: [[vary]] #{i + 1}"
        if not isinstance(ax, dict) or set(ax) - {"key", "values", "label"} or "key" not in ax or "values" not in ax:
            raise UserInputError(f"{where}: expected key = \"section.key\", values = [...], optional label")
        _field_of(where, ax["key"])
        values = ax["values"]
        if not isinstance(values, list) or not 1 <= len(values) <= MAX_VALUES:
            raise UserInputError(f"{where} {ax['key']}: values = {values!r}: expected a list of 1..{MAX_VALUES}")
        same = [_value_key(v) for v in values]   # 1 and 1.0 are one value of a scenario field
        if len(set(same)) != len(values):
            dup = next(v for i, v in enumerate(values) if same[i] in same[:i])
            raise UserInputError(f"{where} {ax['key']}: values = {values!r}: {dup!r} repeats; "
                                 "expected distinct values")
        if "label" in ax and not isinstance(ax["label"], str):
            raise UserInputError(f"{where} {ax['key']}: label = {ax['label']!r}: expected a string (axis label)")
        if ax["key"] in sets:
            raise UserInputError(f"{where} {ax['key']}: also fixed by [set]/--set; vary it or set it, not both")
        if ax["key"] == "starlink.counts" and not all(isinstance(v, int) and not isinstance(v, bool) for v in values):
            raise UserInputError(f"{where} starlink.counts: values = {values!r}: expected single counts "
                                 "(integers; each cell runs one count), e.g. [5, 10, 20]")
        axes.append(Axis(ax["key"], tuple(values), str(ax.get("label", ax["key"]))))
    if len(axes) == 2 and axes[0].key == axes[1].key:
        raise UserInputError(f"{source}: [[vary]] varies {axes[0].key} twice")

    modes = data.get("modes", base.modes)
    count = data.get("count")
    trials = data.get("trials", base.trials)
    if not isinstance(trials, int) or isinstance(trials, bool) or not TRIALS.lo <= trials <= TRIALS.hi:
        raise UserInputError(f"{source}: trials = {trials!r}: expected an integer in {TRIALS.lo:g}..{TRIALS.hi:g}")
    if count is not None and (not isinstance(count, int) or isinstance(count, bool) or count < 1):
        raise UserInputError(f"{source}: count = {count!r}: expected an integer >= 1 (Starlink satellites)")
    grid = expand_grid(axes)
    if len(grid) > MAX_CELLS:
        raise UserInputError(f"{source}: {len(grid)} cells; at most {MAX_CELLS}")

    if not isinstance(data.get("description", ""), str):
        raise UserInputError(f"{source}: description = {data['description']!r}: expected a string (one line)")
    study = Study(name, str(data.get("description", "")), source, base, axes, [], trials, sets, raw=data)
    base_raw = copy.deepcopy(base.raw)
    base_raw.setdefault("monte_carlo", {})["modes"] = modes
    if count is not None:
        base_raw.setdefault("starlink", {})["counts"] = [count]
    for key, value in sets.items():
        apply_setting(base_raw, key, value)
    scn_dir = Path(base.source).parent
    for idx, values in grid:
        raw = copy.deepcopy(base_raw)
        for key, value in values.items():
            apply_setting(raw, key, value)
        label = ", ".join(f"{k}={value_label(v)}" for k, v in values.items())
        try:
            scn = scenario_from_dict(raw, source=f"{source} ({label})", base_dir=scn_dir)
        except UserInputError as exc:
            raise UserInputError(f"{exc} [study cell {label}]") from None
        study.cells.append(Cell(idx, values, scn, max(scn.starlink["counts"])))
    study.modes = list(study.cells[0].scenario.modes)
    return study


def load_study(path: str | Path, sets: list[str] = ()) -> Study:
    """Load a study TOML (a bare name such as `where-is-6-9m` picks a shipped one)."""
    path = Path(path)
    if not path.exists() and (BUILTIN_STUDY_DIR / f"{path.name}.toml").exists():
        path = BUILTIN_STUDY_DIR / f"{path.name}.toml"
    if not path.is_file():
        shipped = ", ".join(shipped_studies())
        raise UserInputError(f"{path}: study file not found (shipped studies: {shipped})")
    data = read_toml_file(path, "study")
    return study_from_dict(data, str(path), path.parent, [parse_set(s) for s in sets])
