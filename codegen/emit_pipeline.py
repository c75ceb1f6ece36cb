"""Plain-C glue for a function that only calls generated functions in sequence (`leonav_predict`,
`leonav_update_<k>`).

A CasADi MX function over its stages copies every argument and result through its own work
vector (about 1,600 doubles per predict: +20 % of its time; 553 per update). The glue emitted
here passes the caller's arrays to the stages directly, keeps only the values between stages
in the work vector, and densifies a sparse intermediate where it is also an output. It exports the same
C API as CasADi-generated code (`<name>_n_in`, `_sparsity_out`, `_work`, ...), so the driver,
ctypes and casadi.external load it like any other generated function, and the tests compare
it with the MX function it stands for (`Pipeline.function`).
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import casadi as ca


@dataclass(frozen=True)
class Step:
    """One call: `callee` with arguments and results named `in:<input>`, `tmp:<name>`, `out:<output>`."""

    callee: ca.Function
    args: tuple[str, ...]
    results: tuple[str, ...]


@dataclass(frozen=True)
class Pipeline:
    """`function` (the MX composition, for its signature and for evaluation) computed by `steps`;
    `densified`: output name -> (the sparse intermediate it is the dense copy of, its pattern).
    A reference may carry a non-zero offset (`tmp:M+120`): a step writing part of a buffer."""

    function: ca.Function
    steps: tuple[Step, ...]
    densified: dict[str, tuple[str, ca.Sparsity]]


def _parse(ref: str) -> tuple[str, str, int]:
    """'tmp:M+120' -> ('tmp', 'M', 120)."""
    kind, _, rest = ref.partition(":")
    key, _, start = rest.partition("+")
    return kind, key, int(start or 0)


def _sizes(header: str, name: str) -> dict[str, int]:
    """SZ_ARG, SZ_RES, SZ_IW, SZ_W of a generated function, read from its header."""
    found = dict(re.findall(rf"#define {re.escape(name)}_(SZ_\w+) (\d+)", header))
    return {k: int(v) for k, v in found.items()}


def _sparsity_c(var: str, sp: ca.Sparsity) -> str:
    """A pattern in CasADi's compact form: [nrow, ncol, 1] when dense, else [nrow, ncol, colind, row]."""
    values = [sp.size1(), sp.size2(), 1] if sp.is_dense() else [sp.size1(), sp.size2(), *sp.colind(), *sp.row()]
    return f"static const casadi_int {var}[{len(values)}] = {{{', '.join(map(str, values))}}};"


def _switch(fn_name: str, ret: str, arg: str, cases: list[str], default: str) -> list[str]:
    lines = [f"CASADI_SYMBOL_EXPORT {ret} {fn_name}(casadi_int {arg}) {{", f"  switch ({arg}) {{"]
    lines += [f"    case {i}: return {c};" for i, c in enumerate(cases)]
    return lines + [f"    default: return {default};", "  }", "}", ""]


def pipeline_c(pipe: Pipeline, headers: dict[str, str], banner: str) -> tuple[str, str]:
    """(C source, header) of the glue; `headers`: the callees' generated headers by name."""
    fn = pipe.function
    name = fn.name()
    ins = {fn.name_in(i): i for i in range(fn.n_in())}
    outs = {fn.name_out(i): i for i in range(fn.n_out())}
    need: dict[str, int] = {}   # values of each intermediate buffer
    for step in pipe.steps:
        for j, ref in enumerate(step.results):
            kind, key, start = _parse(ref)
            if kind == "tmp":
                need[key] = max(need.get(key, 0), start + step.callee.sparsity_out(j).nnz())
    tmps: dict[str, int] = {}
    offset = 0
    for key, size in need.items():
        tmps[key], offset = offset, offset + size
    sizes = {s.callee.name(): _sizes(headers[s.callee.name()], s.callee.name()) for s in pipe.steps}
    sz_arg = max([fn.n_in()] + [v["SZ_ARG"] for v in sizes.values()])
    sz_res = max([fn.n_out()] + [v["SZ_RES"] for v in sizes.values()])
    sz_iw = max(v["SZ_IW"] for v in sizes.values())
    sz_w = offset + max(v["SZ_W"] for v in sizes.values())

    def ref_c(ref: str) -> str:
        kind, key, start = _parse(ref)
        if kind == "in":
            return f"arg[{ins[key]}]"
        if kind == "out":   # a NULL result (not wanted) stays NULL for the part writing into it
            return f"res[{outs[key]}]" if not start else f"(res[{outs[key]}] ? res[{outs[key]}] + {start} : 0)"
        return f"w + {tmps[key] + start}"

    src = [banner.rstrip("\n"), f"/* {name}: {getattr(fn, 'doc', '')} */",
           "/* Glue over generated functions (codegen/emit_pipeline.py): arrays are passed through, not copied. */",
           "#ifdef __cplusplus", 'extern "C" {', "#endif", "",
           "#ifndef casadi_real", "#define casadi_real double", "#endif", "#ifndef casadi_int", "#define casadi_int int",
           "#endif", "#ifndef CASADI_SYMBOL_EXPORT", "#define CASADI_SYMBOL_EXPORT", "#endif", ""]
    for step in pipe.steps:
        src.append(f"int {step.callee.name()}(const casadi_real** arg, casadi_real** res, casadi_int* iw, "
                   "casadi_real* w, int mem);")
    src.append("")
    for k in range(fn.n_in()):
        src.append(_sparsity_c(f"{name}_s_in{k}", fn.sparsity_in(k)))
    for k in range(fn.n_out()):
        src.append(_sparsity_c(f"{name}_s_out{k}", fn.sparsity_out(k)))
    for out_name, (tmp, sp) in pipe.densified.items():
        idx = sp.find()
        src.append(f"static const casadi_int {name}_dense_{out_name}[{len(idx)}] = {{{', '.join(map(str, idx))}}};")
    src += ["", f"CASADI_SYMBOL_EXPORT int {name}(const casadi_real** arg, casadi_real** res, casadi_int* iw, "
            "casadi_real* w, int mem) {",
            f"  const casadi_real* a[{sz_arg}];", f"  casadi_real* r[{sz_res}];",
            f"  casadi_real* ws = w + {offset};  /* the stages' own work, after the values passed between them */",
            "  casadi_int k;", "  (void) mem;"]
    for step in pipe.steps:
        src += [f"  a[{i}] = {ref_c(ref)};" for i, ref in enumerate(step.args)]
        src += [f"  r[{j}] = {ref_c(ref)};" for j, ref in enumerate(step.results)]
        src.append(f"  if ({step.callee.name()}(a, r, iw, ws, 0)) return 1;")
    for out_name, (tmp, sp) in pipe.densified.items():
        o, start = outs[out_name], tmps[tmp]
        n = sp.numel()
        src += [f"  if (res[{o}]) {{", f"    for (k = 0; k < {n}; ++k) res[{o}][k] = 0;",
                f"    for (k = 0; k < {sp.nnz()}; ++k) res[{o}][{name}_dense_{out_name}[k]] = w[{start} + k];", "  }"]
    src += ["  return 0;", "}", ""]
    src += [f"CASADI_SYMBOL_EXPORT int {name}_checkout(void) {{ return 0; }}",
            f"CASADI_SYMBOL_EXPORT void {name}_release(int mem) {{ (void) mem; }}",
            f"CASADI_SYMBOL_EXPORT void {name}_incref(void) {{}}",
            f"CASADI_SYMBOL_EXPORT void {name}_decref(void) {{}}",
            f"CASADI_SYMBOL_EXPORT casadi_int {name}_n_in(void) {{ return {fn.n_in()}; }}",
            f"CASADI_SYMBOL_EXPORT casadi_int {name}_n_out(void) {{ return {fn.n_out()}; }}",
            f"CASADI_SYMBOL_EXPORT casadi_real {name}_default_in(casadi_int i) {{ (void) i; return 0; }}", ""]
    src += _switch(f"{name}_name_in", "const char*", "i", [f'"{fn.name_in(i)}"' for i in range(fn.n_in())], "0")
    src += _switch(f"{name}_name_out", "const char*", "i", [f'"{fn.name_out(i)}"' for i in range(fn.n_out())], "0")
    src += _switch(f"{name}_sparsity_in", "const casadi_int*", "i", [f"{name}_s_in{i}" for i in range(fn.n_in())], "0")
    src += _switch(f"{name}_sparsity_out", "const casadi_int*", "i",
                   [f"{name}_s_out{i}" for i in range(fn.n_out())], "0")
    for suffix, unit in (("work", ""), ("work_bytes", "*sizeof")):
        def size(n, t):
            return f"{n}{unit}({t})" if unit else str(n)
        src += [f"CASADI_SYMBOL_EXPORT int {name}_{suffix}(casadi_int *sz_arg, casadi_int* sz_res, casadi_int *sz_iw, "
                "casadi_int *sz_w) {",
                f"  if (sz_arg) *sz_arg = {size(sz_arg, 'const casadi_real*')};",
                f"  if (sz_res) *sz_res = {size(sz_res, 'casadi_real*')};",
                f"  if (sz_iw) *sz_iw = {size(sz_iw, 'casadi_int')};",
                f"  if (sz_w) *sz_w = {size(sz_w, 'casadi_real')};", "  return 0;", "}", ""]
    src += ["#ifdef __cplusplus", '} /* extern "C" */', "#endif", ""]

    decl = [f"int {name}(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, int mem);",
            f"int {name}_checkout(void);", f"void {name}_release(int mem);", f"void {name}_incref(void);",
            f"void {name}_decref(void);", f"casadi_int {name}_n_in(void);", f"casadi_int {name}_n_out(void);",
            f"casadi_real {name}_default_in(casadi_int i);", f"const char* {name}_name_in(casadi_int i);",
            f"const char* {name}_name_out(casadi_int i);", f"const casadi_int* {name}_sparsity_in(casadi_int i);",
            f"const casadi_int* {name}_sparsity_out(casadi_int i);",
            f"int {name}_work(casadi_int *sz_arg, casadi_int* sz_res, casadi_int *sz_iw, casadi_int *sz_w);",
            f"int {name}_work_bytes(casadi_int *sz_arg, casadi_int* sz_res, casadi_int *sz_iw, casadi_int *sz_w);",
            f"#define {name}_SZ_ARG {sz_arg}", f"#define {name}_SZ_RES {sz_res}", f"#define {name}_SZ_IW {sz_iw}",
            f"#define {name}_SZ_W {sz_w}"]
    hdr = [banner.rstrip("\n"), "#ifdef __cplusplus", 'extern "C" {', "#endif", "",
           "#ifndef casadi_real", "#define casadi_real double", "#endif", "#ifndef casadi_int", "#define casadi_int int",
           "#endif", "", *decl, "", "#ifdef __cplusplus", '} /* extern "C" */', "#endif", ""]
    return "\n".join(src), "\n".join(hdr)
