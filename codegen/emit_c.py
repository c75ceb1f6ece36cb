"""C for the generated functions: one `.c` and one `.h` per function, and their manifest.

Each function becomes `c/<name>.c` with its header `c/<name>.h`, so the diff of a model change
names exactly the functions that changed. A function that calls another generated function
(`functions.build_functions`' `call`) calls it as an external symbol: CasADi emits the
declaration and the call, and sizes the caller's work vectors from the callee's, which it
reads from a compiled callee (`Linker`: each callee compiled once per content into a
temporary shared library, at -O0; only its signature and work sizes are read).

`leonav_gen.h` includes every header (what the driver includes); `leonav_gen.json` lists
every function with its file, its inputs and outputs, the functions it calls, and the
SHA-256 of its C and header text.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import casadi as ca

from leonav.codegen.emit_pipeline import pipeline_c

C_DIR = "c"
"""Sub-folder of gen/ holding one .c/.h pair per generated function."""
CODEGEN_OPTS = {"with_header": True, "casadi_int": "int", "casadi_real": "double", "verbose": False}
# casadi.external reads sparsity patterns as CasADi's own 64-bit integer
LINK_FLAGS = ["-O0", "-shared", "-fPIC", "-Dcasadi_int=long long int"]


def function_c(fn: ca.Function, banner: str) -> tuple[str, str]:
    """(C source, header) of one function, each starting with `banner`."""
    with tempfile.TemporaryDirectory() as tmp:
        cg = ca.CodeGenerator(f"{fn.name()}.c", CODEGEN_OPTS)
        cg.add(fn)
        cg.generate(tmp + "/")
        return tuple(banner + (Path(tmp) / f"{fn.name()}.{ext}").read_text() for ext in ("c", "h"))


class Linker:
    """`call` for generation: a generated callee as a casadi.external of its compiled C."""

    def __init__(self, banner: str):
        self.banner = banner
        self.folder = Path(tempfile.gettempdir()) / "leonav-codegen-link"
        self.folder.mkdir(parents=True, exist_ok=True)

    def __call__(self, fn: ca.Function) -> ca.Function:
        source, _ = function_c(fn, self.banner)
        digest = hashlib.sha256((source + " ".join(LINK_FLAGS)).encode()).hexdigest()[:16]
        so = self.folder / f"{fn.name()}-{digest}.so"
        if not so.exists():
            c_file = self.folder / f"{fn.name()}-{digest}.{os.getpid()}.c"
            c_file.write_text(source)
            tmp = so.with_suffix(f".{os.getpid()}.so")
            compiler = os.environ.get("CC") or shutil.which("cc") or "gcc"
            proc = subprocess.run([compiler, *LINK_FLAGS, str(c_file), "-o", str(tmp), "-lm"],
                                  capture_output=True, text=True)
            c_file.unlink(missing_ok=True)
            if proc.returncode != 0:
                raise RuntimeError(f"codegen: compiling {fn.name()} to link its callers failed "
                                   f"({compiler}): {proc.stderr.strip()[:2000]}")
            tmp.replace(so)   # atomic: concurrent generations never load a partial library
        return ca.external(fn.name(), str(so))


def external_calls(source: str, names: set[str]) -> list[str]:
    """Generated functions a C source declares as external (CasADi's 'External functions' block)."""
    out = []
    for line in source.splitlines():
        head = line.split("(")[0].split()
        if len(head) == 2 and head[0] == "int" and head[1] in names:
            out.append(head[1])
    return out


def write_functions(functions: list[ca.Function], banner: str) -> dict[str, str]:
    """c/<name>.c and .h of every function: {relative path: text}."""
    files: dict[str, str] = {}
    for fn in functions:
        pipeline = getattr(fn, "pipeline", None)
        if pipeline is not None:   # calls generated functions only: plain glue (emit_pipeline.py)
            headers = {s.callee.name(): files[f"{C_DIR}/{s.callee.name()}.h"] for s in pipeline.steps}
            source, header = pipeline_c(pipeline, headers, banner)
        else:
            source, header = function_c(fn, banner)
        files[f"{C_DIR}/{fn.name()}.c"] = source
        files[f"{C_DIR}/{fn.name()}.h"] = header
    return files


def umbrella_header(functions: list[ca.Function], banner: str) -> str:
    """`leonav_gen.h`: every function's header, in generation order."""
    lines = [banner.rstrip("\n"), "/* Every generated function (one .c/.h pair each in c/); see leonav_gen.json. */",
             "#ifndef LEONAV_GEN_H", "#define LEONAV_GEN_H", ""]
    lines += [f'#include "{C_DIR}/{fn.name()}.h"' for fn in functions]
    return "\n".join(lines + ["", "#endif  /* LEONAV_GEN_H */", ""])


def manifest(functions: list[ca.Function], files: dict[str, str]) -> str:
    """`leonav_gen.json`: name, doc, file, shapes, callees and content hash of every function."""
    names = {fn.name() for fn in functions}
    entries = []
    for fn in functions:
        c_text, h_text = files[f"{C_DIR}/{fn.name()}.c"], files[f"{C_DIR}/{fn.name()}.h"]
        entries.append({
            "name": fn.name(),
            "doc": getattr(fn, "doc", ""),
            "file": f"{C_DIR}/{fn.name()}.c",
            "sha256": hashlib.sha256((c_text + h_text).encode()).hexdigest(),
            "lines": c_text.count("\n"),
            "calls": sorted(external_calls(c_text, names - {fn.name()})),
            "inputs": [{"name": fn.name_in(i), "shape": list(fn.size_in(i))} for i in range(fn.n_in())],
            "outputs": [{"name": fn.name_out(i), "shape": list(fn.size_out(i))} for i in range(fn.n_out())],
        })
    return json.dumps({"casadi_version": ca.__version__, "storage": "dense, column-major",
                       "functions": entries}, indent=1) + "\n"
