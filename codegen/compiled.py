"""Compile the generated C with the system compiler and load it through casadi.external.

Used by the tests (independently of the runtime's ctypes loader). The shared library is
cached in the system temp folder under the SHA-256 of the C source. The C is generated
with `casadi_int` = int (for the runtime's driver) behind an `#ifndef`; casadi.external
reads sparsity patterns as CasADi's own 64-bit integer, so this build defines
`casadi_int` as `long long int`. The floating-point code is the same.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import casadi as ca

from leonav.codegen.generate import GEN_NAME, default_output_dir


def compile_shared(c_file: str | Path | None = None) -> Path:
    """Path of `cc -O2 -shared -fPIC` build of `c_file` (default: the committed leonav_gen.c)."""
    c_path = Path(c_file) if c_file else default_output_dir() / f"{GEN_NAME}.c"
    flags = ["-O2", "-shared", "-fPIC", "-Dcasadi_int=long long int"]
    digest = hashlib.sha256(c_path.read_bytes() + " ".join(flags).encode()).hexdigest()[:16]
    folder = Path(tempfile.gettempdir()) / f"leonav-codegen-{digest}"
    so_path = folder / f"{GEN_NAME}.so"
    if so_path.exists():
        return so_path
    folder.mkdir(parents=True, exist_ok=True)
    compiler = os.environ.get("CC") or shutil.which("cc") or "gcc"
    tmp_so = folder / f"{GEN_NAME}.{os.getpid()}.so"
    subprocess.run([compiler, *flags, str(c_path), "-o", str(tmp_so), "-lm"], check=True)
    tmp_so.replace(so_path)  # atomic: concurrent test processes never see a partial file
    return so_path


def external(name: str, so_path: str | Path | None = None) -> ca.Function:
    """The compiled generated function `name` as a casadi.Function."""
    return ca.external(name, str(so_path or compile_shared()))
