"""The generated CasADi functions, built once per test process and only when a test needs them.

Building them takes about a second; at module level in four test files that was paid four times
by every xdist worker at collection, whether or not it ran one of those tests.
"""
from __future__ import annotations

import functools
import json
from collections.abc import Iterator, Mapping
from pathlib import Path

import casadi as ca

MANIFEST = Path(__file__).resolve().parents[1] / "leonav_runtime" / "gen" / "leonav_gen.json"


@functools.cache
def _built() -> dict[str, ca.Function]:
    from leonav.codegen.functions import build_functions

    return {f.name(): f for f in build_functions()}


@functools.cache
def _split() -> dict[str, ca.Function]:
    from leonav.codegen.split import split_large

    return {f.name(): f for f in split_large(list(_built().values()))}


class _Lazy(Mapping):
    """A read-only {name: Function} that builds on first use."""

    def __init__(self, build) -> None:
        self._build = build

    def __getitem__(self, name: str) -> ca.Function:
        return self._build()[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._build())

    def __len__(self) -> int:
        return len(self._build())


FNS: Mapping[str, ca.Function] = _Lazy(_built)        # as the models define them
GENERATED: Mapping[str, ca.Function] = _Lazy(_split)  # as generated: large SX functions in parts


def manifest_names() -> list[str]:
    """Names of the generated functions in the committed manifest (cheap: no CasADi build)."""
    return [f["name"] for f in json.loads(MANIFEST.read_text())["functions"]]
