"""leonav: LEO-aided 9D navigation (IMU + GPS + Starlink Doppler-rate) from Python.

A thin entry point for notebooks and scripts; the code lives in `leonav_runtime`
(see `leonav_runtime.api` and docs/api.md).
"""
from leonav_runtime.api import MODES, Scenario, load_scenario, run_replay, run_study, run_sweep
from leonav_runtime.provenance import version as _version

__version__ = _version()
__all__ = ["MODES", "Scenario", "load_scenario", "run_replay", "run_study", "run_sweep", "__version__"]
