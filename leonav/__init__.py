"""leonav: LEO-aided 9D navigation (IMU + GPS + Starlink Doppler-rate) from Python.

A thin entry point for notebooks and scripts; the code lives in `leonav_runtime`
(see `leonav_runtime.api` and docs/api.md). The repository's `models/`, `codegen/` and
`hardware/` folders install as `leonav.models`, `leonav.codegen` and `leonav.hardware`
(setup.py). The API names load on first use, so `import leonav.models` (the symbolic side)
does not import the runtime.
"""
from __future__ import annotations

_API = ("MODES", "Scenario", "load_scenario", "run_dataset", "run_replay", "run_study", "run_sweep")
__all__ = [*_API, "__version__"]


def __getattr__(name: str):
    if name in _API:
        from leonav_runtime import api

        value = getattr(api, name)
    elif name == "__version__":
        from leonav_runtime.common.provenance import version

        value = version()
    else:
        raise AttributeError(f"module 'leonav' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
