"""Command-line changes to a scenario (`leonav sweep --modes --counts --seed --trials`)
without editing its TOML: the changed values go through the same validation as the file's
(`scenario_from_dict`), and the effective scenario is what the results record."""
from __future__ import annotations

import copy
from pathlib import Path
from typing import Iterable, Sequence

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.scenarios.load import MAX_COUNT, MODES, SCHEMA, Scenario, mode_of, scenario_from_dict


def split_list(values: Iterable[str] | None) -> list[str] | None:
    """['a,b', 'c'] -> ['a', 'b', 'c'] (options take commas and/or spaces)."""
    if values is None:
        return None
    return [v for item in values for v in str(item).replace(",", " ").split() if v]


def _empty_item(values: Iterable[str]) -> bool:
    """Whether a comma list has an empty item ('5,,10', ',5', '5,')."""
    return any(not part.strip() for v in values for part in str(v).split(",")) if values else False


def parse_counts(values: Iterable[str] | None) -> list[int] | None:
    """Starlink counts from '5,10,45' / '5 10 45' / '5:45:5' (start:stop:step, stop included).
    Each count must lie in 1..MAX_COUNT; a range is checked before it is expanded."""
    items = split_list(values)
    if items is None:
        return None
    expected = (f"expected Starlink satellite counts 1..{MAX_COUNT} such as 5,10,45 or a range "
                "start:stop:step such as 5:45:5")
    if _empty_item(values):
        raise UserInputError(f"--counts {','.join(values)!r}: an empty item; {expected}")
    out: list[int] = []
    for item in items:
        try:
            if ":" in item:
                lo, hi, *step = (int(x) for x in item.split(":"))
                step_v = step[0] if step else 1
                if step_v < 1 or hi < lo or len(step) > 1:
                    raise ValueError
            else:
                lo = hi = int(item)
                step_v = 1
        except ValueError:
            raise UserInputError(f"--counts: {item!r}: {expected}") from None
        if lo < 1 or hi > MAX_COUNT:
            raise UserInputError(f"--counts: {item!r}: {expected}")
        out.extend(range(lo, hi + 1, step_v))
    if not out:
        raise UserInputError(f"--counts: {items}: {expected}")
    return out


def apply_overrides(scn: Scenario, *, modes: Sequence[str] | None = None, counts: Sequence[int] | None = None,
                    seed: int | None = None, trials: int | None = None,
                    sets: Sequence[str] = (), api: bool = False) -> tuple[Scenario, dict]:
    """(the scenario with the given values replaced, {option: value} of what changed); sets: --set
    `section.key=value` texts, each value read by the key's declared type (`study.spec.parse_set`).
    api: errors name the Python arguments (`modes=`) rather than the command-line options."""
    def opt(name: str) -> str:
        return f"{name}=" if api else f"--{name} "

    def named(name: str) -> str:
        return name if api else f"--{name}"

    changes: dict = {}
    raw = copy.deepcopy(scn.raw)
    if sets:
        from leonav_runtime.study.spec import apply_setting, parse_set

        for text in sets:
            key, value = parse_set(text)
            apply_setting(raw, key, value)
            changes.setdefault("set", []).append(f"{key}={value}")
    if modes is not None:
        if not modes:
            raise UserInputError(f"{named('modes')}: (none): expected one or more modes, e.g. {', '.join(MODES)}")
        for m in modes:
            mode_of(m, f"{named('modes')}:")
        raw.setdefault("monte_carlo", {})["modes"] = list(dict.fromkeys(modes))
        changes["modes"] = list(dict.fromkeys(modes))
    if counts is not None:
        raw.setdefault("starlink", {})["counts"] = list(counts)
        changes["counts"] = sorted(set(counts))
    if seed is not None:
        if not 0 <= seed < 2**63:
            raise UserInputError(f"{opt('seed')}{seed}: expected an integer in [0, 2^63)")
        raw.setdefault("monte_carlo", {})["seed"] = int(seed)
        changes["seed"] = int(seed)
    if trials is not None:
        bounds = SCHEMA["monte_carlo"]["trials"]
        if not bounds.lo <= trials <= bounds.hi:
            raise UserInputError(f"{opt('trials')}{trials}: expected {bounds.lo:g}..{bounds.hi:g}")
        raw.setdefault("monte_carlo", {})["trials"] = int(trials)
        changes["trials"] = int(trials)
    if not changes:
        return scn, changes
    where = f"{scn.source} with {' '.join(f'{opt(k)}{v}' for k, v in changes.items())}"
    base = Path(scn.source).parent if Path(scn.source).exists() else None
    return scenario_from_dict(raw, source=where if base is None else scn.source, base_dir=base), changes
