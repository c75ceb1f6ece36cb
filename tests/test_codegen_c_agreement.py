"""The compiled generated C agrees with the symbolic CasADi functions (random inputs).

Inputs are drawn from a generator seeded by the CRC-32 of the function's name, so every
run (any PYTHONHASHSEED, any process) checks the same inputs.
"""
from __future__ import annotations

import zlib

import casadi as ca
import numpy as np
import pytest

from leonav.codegen.compiled import compile_shared, external
from tests import symbolic
from leonav_runtime.gen import registry as REG
from leonav_runtime.gen import state_layout as L

FUNCTIONS = symbolic.GENERATED   # as generated: large SX functions in parts (built on first use)
NAMES = symbolic.manifest_names()  # the committed C's functions, for the ids (no build at collection)
# typical magnitude of each nominal-state block and a typical value of each parameter (SI): the registry's
X_SCALE = {s.name: s.typical for s in REG.STATES}
P_VEC = np.zeros(L.NP)
for _q in REG.PARAMS:
    P_VEC[_q.offset] = _q.example


def seed_of(name: str) -> int:
    """Stable seed of a function's inputs (str hash() changes with PYTHONHASHSEED)."""
    return zlib.crc32(name.encode())


@pytest.fixture(scope="module")
def so_path():
    from leonav_runtime.core.compiled import CFLAGS

    return compile_shared(cflags=CFLAGS)   # the code as the runtime compiles it


def _random_input(name: str, shape: tuple[int, int], rng) -> np.ndarray:
    """Physically plausible random values per input name (unit quaternion, SPD matrices...)."""
    rows, cols = shape
    if name in ("P", "J"):
        A = rng.normal(size=(rows, rows))
        return A @ A.T + rows * np.eye(rows)
    if name in ("x", "x0", "x1"):
        x = rng.normal(size=rows)
        for block, scale in X_SCALE.items():
            x[getattr(L, f"X_{block.upper()}_SLICE")] *= scale
        x[L.X_Q_NB_SLICE] /= np.linalg.norm(x[L.X_Q_NB_SLICE])
        return x
    if name == "p":
        return P_VEC
    if name == "aux":
        r_s = np.r_[4.0e6, -4.5e6, 4.9e6]
        aux = np.zeros(L.NAUX)
        aux[L.AUX_R_S_ECEF_SLICE] = r_s
        aux[L.AUX_V_S_ECEF_SLICE] = rng.normal(size=3) * 5e3
        aux[L.AUX_A_S_ECEF_SLICE] = rng.normal(size=3) * 8
        aux[L.AUX_R_REF_ECEF_SLICE] = r_s + rng.normal(size=3) * 5e5
        aux[L.AUX_V_REF_ECEF_SLICE] = rng.normal(size=3) * 5e3
        aux[L.AUX_A_REF_ECEF_SLICE] = rng.normal(size=3) * 8
        aux[L.AUX_F_B_SLICE] = rng.normal(size=3) + [0, 0, 9.8]
        return aux
    if name == "dt":
        return np.array([0.01 + 0.1 * rng.random()])
    if name == "u":
        u = rng.normal(size=L.NU)
        u[L.U_DTHETA_B_SLICE] *= 1e-2
        u[L.U_DVEL_B_SLICE] *= 0.1
        return u
    if name == "q":
        q = rng.normal(size=4)
        return q / np.linalg.norm(q)
    if name == "R":
        return np.array([0.5 + rng.random()])
    return rng.normal(size=rows * cols).reshape((rows, cols), order="F") * (1e3 if name == "p_enu" else 1.0)


def _sparse_as_declared(value: np.ndarray, sparsity) -> np.ndarray | ca.DM:
    """A stage function's sparse input (F, G of the predict stages) keeps only its structural non-zeros."""
    if sparsity.is_dense():
        return value
    dense = np.array(value, dtype=float).reshape(sparsity.shape, order="F")
    return ca.DM(sparsity, dense.ravel(order="F")[sparsity.find()])


def test_the_committed_functions_are_the_ones_built():
    assert sorted(NAMES) == sorted(FUNCTIONS)


@pytest.mark.parametrize("name", NAMES)
def test_compiled_matches_symbolic(name, so_path):
    fn = FUNCTIONS[name]
    compiled = external(fn.name(), so_path)
    assert compiled.n_in() == fn.n_in() and compiled.n_out() == fn.n_out()
    rng = np.random.default_rng(seed_of(fn.name()))
    for _ in range(5):
        args = [_sparse_as_declared(_random_input(fn.name_in(i), fn.size_in(i), rng), fn.sparsity_in(i))
                for i in range(fn.n_in())]
        ref, got = fn(*args), compiled(*args)
        ref = ref if isinstance(ref, (list, tuple)) else [ref]
        got = got if isinstance(got, (list, tuple)) else [got]
        for i, (a, b) in enumerate(zip(ref, got)):
            a, b = np.array(ca.densify(a)), np.array(ca.densify(b))
            assert a.shape == b.shape == fn.size_out(i)
            assert np.isfinite(a).all(), f"{fn.name()} output {fn.name_out(i)} not finite"
            scale = max(np.abs(a).max(), 1e-300)
            np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-12 * scale,
                                       err_msg=f"{fn.name()} output {fn.name_out(i)}")


def test_outputs_are_dense(so_path):
    """The driver reads every output as a dense column-major array (the predict's internal
    stages pass sparse F, G between themselves only)."""
    for fn in (f for f in FUNCTIONS.values() if not getattr(f, "internal", False)):
        for i in range(fn.n_out()):
            assert fn.sparsity_out(i).is_dense(), f"{fn.name()}:{fn.name_out(i)} is sparse"
