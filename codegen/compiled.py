"""Compile the generated C with the system compiler and load it through casadi.external.

Used by the tests (independently of the runtime's ctypes loader). The shared library is
cached in the system temp folder under the SHA-256 of the C sources. The C is generated
with `casadi_int` = int (for the runtime's driver) behind an `#ifndef`; casadi.external
reads sparsity patterns as CasADi's own 64-bit integer, so this build defines
`casadi_int` as `long long int`. The floating-point code is the same.
"""
from __future__ import annotations

import fcntl
import hashlib
import os
import shutil
import subprocess
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Sequence

import casadi as ca

from leonav.codegen.emit_c import C_DIR
from leonav.codegen.generate import GEN_NAME, default_output_dir


def compile_shared(gen_dir: str | Path | None = None, cflags: Sequence[str] = ("-O2",)) -> Path:
    """Path of a `cc CFLAGS -shared` build of every generated function in `gen_dir`/c
    (default: the committed leonav_runtime/gen/); pass the runtime's flags
    (leonav_runtime.core.compiled.CFLAGS) to check the code as the runtime compiles it."""
    c_files = sorted((Path(gen_dir) if gen_dir else default_output_dir()).joinpath(C_DIR).glob("*.c"))
    if not c_files:
        raise FileNotFoundError(f"no generated C in {gen_dir or default_output_dir()}/{C_DIR}")
    flags = [*cflags, "-fPIC", "-Dcasadi_int=long long int"]
    digest = hashlib.sha256((" ".join(flags) + "\0shared").encode())
    for path in c_files:
        digest.update(path.name.encode() + b"\0" + path.read_bytes())
    folder = Path(tempfile.gettempdir()) / f"leonav-codegen-{digest.hexdigest()[:16]}"
    so_path = folder / f"{GEN_NAME}.so"
    if so_path.exists():
        return so_path
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / ".lock", "a") as lock:  # processes starting at once: one compiles, the others wait
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not so_path.exists():
            _compile_into(folder, c_files, flags, so_path)
    return so_path


def _compile_into(folder: Path, c_files: list[Path], flags: list[str], so_path: Path) -> None:
    """Compile every generated function in parallel and link `so_path` (renamed into place)."""
    compiler = os.environ.get("CC") or shutil.which("cc") or "gcc"
    objects = [folder / f"{path.stem}.{os.getpid()}.o" for path in c_files]

    def compile_one(pair):
        path, obj = pair
        subprocess.run([compiler, *flags, "-c", str(path), "-o", str(obj)], check=True)

    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
        list(pool.map(compile_one, zip(c_files, objects)))
    tmp_so = folder / f"{GEN_NAME}.{os.getpid()}.so"
    subprocess.run([compiler, "-shared", *map(str, objects), "-o", str(tmp_so), "-lm"], check=True)
    for obj in objects:
        obj.unlink()
    tmp_so.replace(so_path)  # atomic: concurrent test processes never see a partial file


def external(name: str, so_path: str | Path | None = None) -> ca.Function:
    """The compiled generated function `name` as a casadi.Function."""
    return ca.external(name, str(so_path or compile_shared()))
