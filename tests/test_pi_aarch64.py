"""The Pi path: `leonav export-records` feeds hardware/pi/leonav_filter, and aarch64 builds (cross
`aarch64-linux-gnu-gcc`, run under `qemu-aarch64`) of the program and of the library give the x86
run bit for bit. Skips with the reason when the cross tools are absent (Debian packages
`gcc-aarch64-linux-gnu`, `qemu-user`)."""
from __future__ import annotations

import csv
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import pi_program

ROOT = Path(__file__).resolve().parents[1]
PI = ROOT / "hardware" / "pi"
GEN, CSRC = ROOT / "leonav_runtime" / "gen", ROOT / "leonav_runtime" / "csrc"
SYSROOT = Path("/usr/aarch64-linux-gnu")
CROSS = "aarch64-linux-gnu-gcc"


def _need(*tools: str) -> None:
    missing = [t for t in tools if shutil.which(t) is None]
    if missing:
        pytest.skip(f"needs {', '.join(missing)} (Debian: apt-get install gcc-aarch64-linux-gnu qemu-user make gcc)")


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """A short synthetic session with beacons, exported for fix+leo-alpha+imu."""
    from leonav_runtime.commands.export_records import export
    from leonav_runtime.replay import ReplayOptions
    from leonav_runtime.simulation.session_synth import SynthSessionConfig, write_synthetic_session

    base = tmp_path_factory.mktemp("pi")
    write_synthetic_session(base / "s", SynthSessionConfig(seconds=6.0, seed=3, sdr_rate_hz=200e3, n_satellites=3))
    out = base / "x"
    out.mkdir()
    info = export(base / "s", out, ReplayOptions(modes=("fix+leo-alpha+imu",)))
    assert info["records_per_kind"].get("doppler_rate", 0) > 0, "the export should carry Doppler-rate records"
    return out, info


@pytest.fixture(scope="module")
def x86_program() -> Path:
    return pi_program()


def _run(argv, env=None) -> subprocess.CompletedProcess:
    run = subprocess.run(argv, capture_output=True, text=True, env=env, timeout=120)
    assert run.returncode == 0, run.stderr
    return run


def _rows(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.mark.parametrize("interval", [None, 0.5])
def test_export_records_runs_in_the_pi_program_as_in_python(exported, x86_program, interval):
    """The program's run equals EKF.run bit for bit, variances included; with a covariance
    interval (its 5th argument, after the gate) too."""
    from leonav_runtime.core.filter import EKF
    from leonav_runtime.gen import state_layout as L
    from leonav_runtime.gen.constants import CHI2_1DOF_999
    from leonav_runtime.core.records import RECORD_DTYPE

    out, info = exported
    extra = [] if interval is None else [repr(CHI2_1DOF_999), repr(interval)]
    _run([str(x86_program), str(out / "records.bin"), str(out / "init.bin"), str(out / "x86.csv"), *extra])
    recs = np.fromfile(out / "records.bin", dtype=RECORD_DTYPE)
    init = np.fromfile(out / "init.bin", dtype="<f8")
    assert recs.size == info["records"] and init.size == L.NX + L.NDX**2 + L.NP
    x0, P0, p = init[:L.NX], init[L.NX:L.NX + L.NDX**2].reshape((L.NDX, L.NDX), order="F"), init[L.NX + L.NDX**2:]
    ref = EKF(x0, P0, p).run(recs, covariance_interval_s=interval or 0.0)
    rows = _rows(out / "x86.csv")
    x = np.array([[float(r[f"x{i}"]) for i in range(L.NX)] for r in rows])
    np.testing.assert_array_equal(x, ref.x)                     # %.17g round-trips: bit for bit
    np.testing.assert_array_equal([int(r["status"]) for r in rows], ref.status)
    pd = np.array([[float(r[f"P{i}"]) for i in range(L.NDX)] for r in rows])
    np.testing.assert_array_equal(pd, ref.P_diag)


@pytest.mark.slow
def test_aarch64_program_and_library_equal_the_x86_run_bit_for_bit(exported, x86_program, tmp_path):
    _need(CROSS, "qemu-aarch64")
    if not SYSROOT.is_dir():
        pytest.skip(f"needs the aarch64 C library at {SYSROOT} (Debian: libc6-dev-arm64-cross)")
    out, _ = exported
    records, init = str(out / "records.bin"), str(out / "init.bin")
    _run([str(x86_program), records, init, str(tmp_path / "x86.csv")])
    # the program as the Makefile builds it for a 64-bit Pi
    env = os.environ | {"QEMU_LD_PREFIX": str(SYSROOT)}
    _run(["qemu-aarch64", str(pi_program(CROSS)), records, init, str(tmp_path / "arm.csv")], env)
    # the library as the runtime builds it (leonav_runtime.core.compiled: the Makefile's flags, so
    # the generated functions' objects are the Makefile's; the driver compiled the same way), the
    # program linked to it
    from leonav_runtime.core.compiled import CFLAGS

    flags = [*CFLAGS, f"-I{GEN}", f"-I{CSRC}"]
    objs = sorted(str(o) for o in (pi_program(CROSS).parent / "gen").glob("*.o"))
    assert len(objs) == len(list((GEN / "c").glob("*.c")))
    _run([CROSS, *flags, "-c", str(CSRC / "leonav_driver.c"), "-o", str(tmp_path / "leonav_driver.o")])
    objs.append(str(tmp_path / "leonav_driver.o"))
    _run([CROSS, "-shared", "-o", str(tmp_path / "libleonav.so"), *objs, "-lm"])
    _run([CROSS, *(f for f in CFLAGS if f != "-fPIC"), f"-I{GEN}", f"-I{CSRC}", "-o", str(tmp_path / "filter_lib"),
          str(PI / "leonav_filter.c"), f"-L{tmp_path}", "-lleonav", "-lm"])
    _run(["qemu-aarch64", str(tmp_path / "filter_lib"), records, init, str(tmp_path / "arm_lib.csv")],
         env | {"LD_LIBRARY_PATH": str(tmp_path)})
    ref = (tmp_path / "x86.csv").read_bytes()
    assert (tmp_path / "arm.csv").read_bytes() == ref
    assert (tmp_path / "arm_lib.csv").read_bytes() == ref


def test_the_makefile_builds_with_the_runtimes_flags():
    """The Pi program and the runtime's library come from the same objects only if the flags agree."""
    from leonav_runtime.core.compiled import CFLAGS

    line = next(l for l in (PI / "Makefile").read_text().splitlines() if l.startswith("CFLAGS"))
    assert line.split("?=", 1)[1].split() == list(CFLAGS)
