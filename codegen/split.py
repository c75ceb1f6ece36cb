"""Keep every generated C file reviewable: an SX function over `BUDGET` instructions is
generated as parts, each computing a contiguous range of one output's non-zeros, under the
original name as plain glue over its parts (emit_pipeline.py).

A part computes its outputs with exactly the expressions the whole function has, so the
values are the same to the bit; subexpressions shared by two parts are computed in both
(order outputs so that neighbouring non-zeros share their inputs: the predict's pre-state
covariance is passed as its lower triangle, whose column-major ranges are row blocks).
A pipeline step whose callee was split becomes one step per part, each writing its range of
the same buffer.
"""
from __future__ import annotations

import casadi as ca

from leonav.codegen.emit_pipeline import Pipeline, Step

BUDGET = 4000
"""Instructions per generated SX function (its C file is about 250 lines longer)."""


def _instructions(inputs: list, expr) -> int:
    return ca.Function("probe", inputs, [expr], {"cse": True}).n_instructions()


def _cut(inputs: list, nz, start: int, budget: int) -> int:
    """Largest end such that nz[start:end] fits the budget (at least one non-zero)."""
    lo, hi = start + 1, nz.shape[0]
    if _instructions(inputs, nz[start:hi]) <= budget:
        return hi
    while hi - lo > 1:   # invariant: nz[start:lo] fits (or lo == start + 1), nz[start:hi] does not
        mid = (lo + hi) // 2
        if _instructions(inputs, nz[start:mid]) <= budget:
            lo = mid
        else:
            hi = mid
    return lo


def parts_of(fn: ca.Function, budget: int = BUDGET) -> list[tuple[ca.Function, int, int]] | None:
    """None when `fn` fits the budget (or is not SX); else [(part, output index, first non-zero)]."""
    if not fn.is_a("SXFunction") or fn.n_instructions() <= budget:
        return None
    inputs = fn.sx_in()
    outputs = fn.call(inputs)
    parts = []
    for o, out in enumerate(outputs):
        nz = ca.vertcat(*[out.nz[k] for k in range(out.nnz())]) if out.nnz() else ca.SX(0, 1)
        start = 0
        while start < out.nnz():
            end = _cut(inputs, nz, start, budget)
            part = ca.Function(f"{fn.name()}_{len(parts) + 1}", inputs, [nz[start:end]],
                               [fn.name_in(i) for i in range(fn.n_in())], [f"{fn.name_out(o)}_nz_{start}"],
                               {"cse": True})
            part.doc = f"part {len(parts) + 1} of {fn.name()}: non-zeros {start}..{end - 1} of {fn.name_out(o)}"
            part.internal = True
            parts.append((part, o, start))
            start = end
    return parts


def _offset(ref: str, start: int) -> str:
    return ref if start == 0 else f"{ref}+{start}"


def split_large(functions: list[ca.Function], budget: int = BUDGET) -> list[ca.Function]:
    """`functions` with every SX function over the budget replaced by its parts and a glue
    function of the same name (and pipelines calling it calling its parts)."""
    split: dict[str, list[tuple[ca.Function, int, int]]] = {}
    out: list[ca.Function] = []
    for fn in functions:
        pipeline = getattr(fn, "pipeline", None)
        if pipeline is not None:
            steps = []
            for step in pipeline.steps:
                if step.callee.name() not in split:
                    steps.append(step)
                    continue
                for part, o, start in split[step.callee.name()]:
                    steps.append(Step(part, step.args, (_offset(step.results[o], start),)))
            fn.pipeline = Pipeline(pipeline.function, tuple(steps), pipeline.densified)
            out.append(fn)
            continue
        parts = parts_of(fn, budget)
        if parts is None:
            out.append(fn)
            continue
        split[fn.name()] = parts
        if getattr(fn, "internal", False):   # reached through a pipeline only: its parts replace it there
            out += [p for p, _, _ in parts]
            continue
        args = tuple(f"in:{fn.name_in(i)}" for i in range(fn.n_in()))
        if not all(fn.sparsity_out(o).is_dense() for o in range(fn.n_out())):
            raise ValueError(f"codegen: {fn.name()} is over {budget} instructions and has a sparse output; "
                             "split it in models/ or mark it internal")
        steps = tuple(Step(p, args, (_offset(f"out:{fn.name_out(o)}", start),)) for p, o, start in parts)
        out += [p for p, _, _ in parts]
        fn.pipeline = Pipeline(fn, steps, {})
        out.append(fn)
    return out
