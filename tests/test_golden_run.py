"""A seeded trial reproduces the committed golden run (any behaviour change shows as a diff)."""
from __future__ import annotations

import numpy as np

from tests.golden_run import COLUMNS, GOLDEN, golden_rows, read_golden

# Tolerances in physical units: far above rounding differences between compilers/libm,
# far below any change of a model, the generated code, the driver or the simulator.
ABS_TOL = {"m": 1e-6, "mps": 1e-8, "q": 1e-10, "hz": 1e-5}


def _tol(column: str) -> float:
    if column.startswith("q"):
        return ABS_TOL["q"]
    if column.endswith("_hz"):
        return ABS_TOL["hz"]
    return ABS_TOL["mps"] if column.endswith("_mps") else ABS_TOL["m"]


def test_golden_run_is_reproduced():
    expected = np.array(read_golden())
    got = np.array(golden_rows())
    assert got.shape == expected.shape, "row count changed; if intended: python -m tests.golden_run --update"
    for j, name in enumerate(COLUMNS):
        diff = np.max(np.abs(got[:, j] - expected[:, j]))
        assert diff <= _tol(name), (
            f"{name} differs from {GOLDEN.name} by {diff:.3g}; if the change is intended, "
            "regenerate with: python -m tests.golden_run --update")
