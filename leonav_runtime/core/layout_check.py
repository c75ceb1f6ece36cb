"""The loaded library against the generated layout: every generated function the driver
calls has the number and shapes of inputs and outputs that gen/state_layout.py says."""
from __future__ import annotations

import ctypes
import importlib.util
from pathlib import Path
from types import ModuleType

from leonav_runtime.core.build_cache import CompilerError

_c_int_p = ctypes.POINTER(ctypes.c_int)


class LayoutMismatchError(RuntimeError):
    """The compiled generated functions do not match gen/state_layout.py."""


def load_layout(gen_dir: Path) -> ModuleType:
    """Import gen/state_layout.py (the Python twin of state_layout.h) from gen_dir."""
    path = Path(gen_dir) / "state_layout.py"
    if not path.exists():
        raise CompilerError(f"{path} is missing: run `python -m leonav.codegen`")
    spec = importlib.util.spec_from_file_location(f"_leonav_state_layout_{abs(hash(str(path)))}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


def measurement_ids(layout: ModuleType) -> dict[str, int]:
    """Observable function suffix (e.g. 'pseudorange') -> LEONAV_MEAS_* id, from the generated
    observable table (`MEAS_TABLE`, twin of the C driver's LEONAV_MEAS_TABLE)."""
    return {str(m.suffix): int(m.kind) for m in layout.MEAS_TABLE}


def expected_shapes(layout: ModuleType) -> dict[str, tuple[list[tuple[int, int]], list[tuple[int, int]]]]:
    """Generated function name -> (input shapes, output shapes) required by the driver."""
    nx, ndx, naux, np_, nu = layout.NX, layout.NDX, layout.NAUX, layout.NP, layout.NU
    x, P, u, s, p, aux = (nx, 1), (ndx, ndx), (nu, 1), (1, 1), (np_, 1), (naux, 1)
    shapes = {
        "leonav_mech": ([x, u, s, p], [x]),
        "leonav_predict": ([x, P, u, s, p], [x, P, P, P]),
        "leonav_predict_cv": ([x, P, s, p], [x, P, P, P]),
        "leonav_boxplus": ([x, (ndx, 1)], [x]),
        "leonav_gnss_terms": ([x, aux, p], [(4, 1)]),
        "leonav_boxminus": ([x, x], [(ndx, 1)]),
        "leonav_pcrb_update": ([P, (1, ndx), s], [P, s]),
    }
    for m in layout.MEAS_TABLE:
        z = (m.dim, 1)
        shapes[f"leonav_h_{m.suffix}"] = ([x, aux, p], [z, (m.dim, ndx)])
        shapes[f"leonav_update_{m.suffix}"] = ([x, P, z, s, aux, p], [x, P, z, s, s])
        shapes[f"leonav_pcrb_info_{m.suffix}"] = ([P, x, aux, p, s], [P])
    return shapes


def _sparsity_shape(sp) -> tuple[int, int]:
    return int(sp[0]), int(sp[1])  # CasADi sparsity starts with nrow, ncol


def check_layout(lib: ctypes.CDLL, layout: ModuleType) -> None:
    """Compare every generated function's n_in/n_out and shapes with state_layout.py."""
    problems = []
    for name, (ins, outs) in expected_shapes(layout).items():
        try:
            n_in, n_out = getattr(lib, name + "_n_in"), getattr(lib, name + "_n_out")
        except AttributeError:
            problems.append(f"{name}: missing from the library")
            continue
        sp_in, sp_out = getattr(lib, name + "_sparsity_in"), getattr(lib, name + "_sparsity_out")
        for fn, ret in ((n_in, ctypes.c_int), (n_out, ctypes.c_int)):
            fn.restype, fn.argtypes = ret, []
        for fn in (sp_in, sp_out):
            fn.restype, fn.argtypes = _c_int_p, [ctypes.c_int]
        for label, count, sparsity, want in (("inputs", n_in(), sp_in, ins), ("outputs", n_out(), sp_out, outs)):
            if count != len(want):
                problems.append(f"{name}: {count} {label}, expected {len(want)}")
                continue
            for i, shape in enumerate(want):
                got = _sparsity_shape(sparsity(i))
                if got != shape:
                    problems.append(f"{name}: {label[:-1]} {i} is {got[0]}x{got[1]}, expected {shape[0]}x{shape[1]}")
                if label == "inputs" and sparsity(i)[2] != 1:
                    problems.append(f"{name}: input {i} is sparse; the driver passes dense arrays")
    if problems:
        raise LayoutMismatchError("generated code does not match state_layout.py:\n  " + "\n  ".join(problems))
