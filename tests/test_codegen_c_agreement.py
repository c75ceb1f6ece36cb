"""The compiled generated C agrees with the symbolic CasADi functions (random inputs)."""
from __future__ import annotations

import numpy as np
import pytest

from codegen.compiled import compile_shared, external
from codegen.functions import build_functions

FUNCTIONS = build_functions()


@pytest.fixture(scope="module")
def so_path():
    return compile_shared()


def _random_input(name: str, shape: tuple[int, int], rng) -> np.ndarray:
    """Physically plausible random values per input name (unit quaternion, SPD matrices...)."""
    rows, cols = shape
    if name in ("P", "J"):
        A = rng.normal(size=(rows, rows))
        return A @ A.T + rows * np.eye(rows)
    if name in ("x", "x0", "x1"):
        x = rng.normal(size=rows) * np.r_[300, 300, 30, 5, 5, 1, 1, 1, 1, 1, 1e-2 * np.ones(3), 1e-3 * np.ones(3), 1e3, 10, 1e3]
        x[6:10] /= np.linalg.norm(x[6:10])
        return x
    if name == "p":
        return np.r_[0.75, -1.35, 170.0, 1e-3, 1e-4, 1e-5, 1e-7, 0.01, 0.03, 0.01, 11.325e9]
    if name == "aux":
        r_s = np.r_[4.0e6, -4.5e6, 4.9e6]
        return np.r_[r_s, rng.normal(size=3) * 5e3, rng.normal(size=3) * 8, r_s + rng.normal(size=3) * 5e5,
                     rng.normal(size=3) * 5e3, rng.normal(size=3) * 8, rng.normal(size=3) + [0, 0, 9.8]]
    if name == "dt":
        return np.array([0.01 + 0.1 * rng.random()])
    if name == "u":
        return rng.normal(size=6) * np.r_[1e-2 * np.ones(3), 0.1 * np.ones(3)]
    if name == "q":
        q = rng.normal(size=4)
        return q / np.linalg.norm(q)
    if name == "R":
        return np.array([0.5 + rng.random()])
    return rng.normal(size=rows * cols).reshape((rows, cols), order="F") * (1e3 if name == "p_enu" else 1.0)


@pytest.mark.parametrize("fn", FUNCTIONS, ids=[f.name() for f in FUNCTIONS])
def test_compiled_matches_symbolic(fn, so_path):
    compiled = external(fn.name(), so_path)
    assert compiled.n_in() == fn.n_in() and compiled.n_out() == fn.n_out()
    rng = np.random.default_rng(abs(hash(fn.name())) % 2**32)
    for _ in range(5):
        args = [_random_input(fn.name_in(i), fn.size_in(i), rng) for i in range(fn.n_in())]
        ref, got = fn(*args), compiled(*args)
        ref = ref if isinstance(ref, (list, tuple)) else [ref]
        got = got if isinstance(got, (list, tuple)) else [got]
        for i, (a, b) in enumerate(zip(ref, got)):
            a, b = np.array(a), np.array(b)
            assert a.shape == b.shape == fn.size_out(i)
            assert np.isfinite(a).all(), f"{fn.name()} output {fn.name_out(i)} not finite"
            scale = max(np.abs(a).max(), 1e-300)
            np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-12 * scale,
                                       err_msg=f"{fn.name()} output {fn.name_out(i)}")


def test_outputs_are_dense(so_path):
    """The driver reads every output as a dense column-major array."""
    for fn in FUNCTIONS:
        for i in range(fn.n_out()):
            assert fn.sparsity_out(i).is_dense(), f"{fn.name()}:{fn.name_out(i)} is sparse"
