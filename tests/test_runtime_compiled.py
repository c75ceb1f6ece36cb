"""Compile cache, loader checks, and the no-casadi guarantee of the filter path."""
from __future__ import annotations

import shutil
import subprocess
import sys
import types

import pytest

from leonav_runtime.core import compiled

NO_CASADI_SCRIPT = r"""
import sys
sys.modules["casadi"] = None  # any `import casadi` now raises ImportError
import math
import numpy as np
from leonav_runtime.core import compiled, records, filter as lf
from leonav_runtime.gen import state_layout as L
lib = compiled.load()
p = np.zeros(L.NP)
p[L.P_LAT0_RAD], p[L.P_H0_M], p[L.P_VRW], p[L.P_ARW] = math.radians(45), 100.0, 1e-3, 1e-4
x = np.zeros(L.NX); x[L.X_Q_NB] = 1.0
u = lf.stationary_imu(x, 0.01, p, lib)
t = np.arange(1, 101) * 0.01
recs = records.merge_records(
    records.imu_records(t, np.tile(u[L.U_DTHETA_B_SLICE], (100, 1)), np.tile(u[L.U_DVEL_B_SLICE], (100, 1))),
    records.measurement_records([0.5, 1.0], L.MEAS_POS_E, [0.0, 0.0], 1.0))
res = lf.EKF(x, np.eye(L.NDX), p, library=lib).run(recs)
assert res.n_imu == 100 and res.n_applied == 2, (res.n_imu, res.n_applied)
assert not any(m == "casadi" or m.startswith("casadi.") for m, v in sys.modules.items() if v is not None)
print("ok")
"""


def test_filter_path_never_imports_casadi():
    proc = subprocess.run([sys.executable, "-c", NO_CASADI_SCRIPT], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "ok"


def test_second_load_uses_the_cache_and_same_library():
    first = compiled.load()
    compiled.clear_process_cache()
    again = compiled.build()
    assert again.compiled_objects == [] and not again.linked and again.compile_time_s == 0.0
    assert again.library == first.build.library and again.key == first.build.key
    assert compiled.load() is not first  # a fresh ctypes load of the cached file


def test_changed_source_or_flags_give_a_new_key(tmp_path):
    gen, csrc = tmp_path / "gen", tmp_path / "csrc"
    shutil.copytree(compiled.GEN_DIR, gen)
    shutil.copytree(compiled.CSRC_DIR, csrc)
    version = compiled.compiler_version(compiled.compiler())
    includes = [gen, csrc]
    driver = csrc / "leonav_driver.c"
    key = compiled.object_key(driver, includes, compiled.cflags(), version)
    assert key == compiled.object_key(compiled.CSRC_DIR / "leonav_driver.c",
                                      [compiled.GEN_DIR, compiled.CSRC_DIR], compiled.cflags(), version)
    driver.write_text(driver.read_text() + "\n/* changed */\n")
    assert compiled.object_key(driver, includes, compiled.cflags(), version) != key
    header = gen / "state_layout.h"  # a header change invalidates what includes it (the driver)...
    key = compiled.object_key(driver, includes, compiled.cflags(), version)
    gen_c = gen / "c" / "leonav_h_pos_e.c"
    gen_key = compiled.object_key(gen_c, includes, compiled.cflags(), version)
    header.write_text(header.read_text() + "\n")
    assert compiled.object_key(driver, includes, compiled.cflags(), version) != key
    # ... but not a generated function, which includes no project header
    assert compiled.object_key(gen_c, includes, compiled.cflags(), version) == gen_key
    other = gen / "c" / "leonav_h_pos_n.c"
    other.write_text(other.read_text() + "\n")
    assert compiled.object_key(gen_c, includes, compiled.cflags(), version) == gen_key
    gen_c.write_text(gen_c.read_text() + "\n")
    assert compiled.object_key(gen_c, includes, compiled.cflags(), version) != gen_key
    assert compiled.object_key(gen_c, includes, compiled.cflags() + ["-O3"], version) != \
        compiled.object_key(gen_c, includes, compiled.cflags(), version)
    assert compiled.object_key(gen_c, includes, compiled.cflags(), version + "x") != \
        compiled.object_key(gen_c, includes, compiled.cflags(), version)


def test_layout_mismatch_is_reported():
    lib = compiled.load()
    wrong = types.SimpleNamespace(**{k: getattr(lib.layout, k) for k in ("NX", "NDX", "NP", "NAUX", "NU",
                                                                         "MEAS_TABLE")})
    naux = wrong.NAUX
    wrong.NAUX += 1
    with pytest.raises(compiled.LayoutMismatchError,
                       match=rf"leonav_h_pseudorange: input 1 is {naux}x1, expected {naux + 1}x1"):
        compiled.check_layout(lib.lib, wrong)
    wrong.NAUX -= 1
    Observable = type(wrong.MEAS_TABLE[0])
    wrong.MEAS_TABLE = tuple(wrong.MEAS_TABLE) + (Observable(len(wrong.MEAS_TABLE), "future_sensor", 1, "FUTURE_SENSOR", "m"),)
    with pytest.raises(compiled.LayoutMismatchError, match="leonav_h_future_sensor: missing"):
        compiled.check_layout(lib.lib, wrong)


def test_missing_compiler_and_compile_errors_are_clear(monkeypatch, tmp_path):
    monkeypatch.setenv("CC", "/nonexistent/cc")
    with pytest.raises(compiled.CompilerError, match="no C compiler found"):
        compiled.build()
    monkeypatch.delenv("CC")
    gen, csrc = tmp_path / "gen", tmp_path / "csrc"
    (gen / "c").mkdir(parents=True)
    csrc.mkdir()
    (gen / "c" / "tiny_gen.c").write_text("int tiny(void) { return 1; }\n")
    (csrc / "broken.c").write_text("int broken(void) { return undeclared_name; }\n")
    with pytest.raises(compiled.CompilerError, match="undeclared_name"):
        compiled.build(gen, csrc, out_dir=tmp_path / "build")


def test_generated_tables_reach_the_driver():
    """The driver's observable table and code names come from the generated lists."""
    lib = compiled.load()
    L = lib.layout
    for m in L.MEAS_TABLE:
        assert lib.lib.leonav_meas_name(m.kind).decode() == m.name
        assert lib.lib.leonav_meas_unit(m.kind).decode() == m.unit
    assert lib.lib.leonav_meas_name(L.NMEAS) is None and lib.lib.leonav_meas_name(L.MEAS_IMU) is None
    for rc, name in L.RETURN_NAMES.items():
        assert lib.lib.leonav_code_name(rc).decode() == name == compiled.code_name(rc)
    assert lib.meas_ids == {m.suffix: m.kind for m in L.MEAS_TABLE}
