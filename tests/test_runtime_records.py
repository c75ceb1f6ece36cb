"""Record dtype == C struct layout; merge order rule; stream checks."""
from __future__ import annotations

import ctypes
import shlex
import subprocess

import numpy as np
import pytest

from leonav_runtime.core import compiled, records


def _c_offsets(tmp_path) -> dict[str, int]:
    """offsetof/sizeof of leonav_record and leonav_run_out, from a C probe program."""
    fields_rec = ["t", "kind", "sat_id", "z", "R", "dt", "u", "aux"]
    fields_out = [name for name, _ in compiled.RunOut._fields_]   # the C names the ctypes twin claims
    lines = ['#include <stdio.h>', '#include <stddef.h>', '#include "leonav_driver.h"', "int main(void) {"]
    lines += [f'  printf("rec.{f} %zu\\n", offsetof(leonav_record, {f}));' for f in fields_rec]
    lines += [f'  printf("out.{f} %zu\\n", offsetof(leonav_run_out, {f}));' for f in fields_out]
    lines += ['  printf("rec.size %zu\\n", sizeof(leonav_record));',
              '  printf("out.size %zu\\n", sizeof(leonav_run_out));', "  return 0;", "}"]
    src = tmp_path / "probe.c"
    src.write_text("\n".join(lines) + "\n")
    exe = tmp_path / "probe"
    cc = shlex.split(compiled.compiler())
    subprocess.run(cc + ["-std=c99", f"-I{compiled.GEN_DIR}", f"-I{compiled.CSRC_DIR}", str(src), "-o", str(exe)],
                   check=True, capture_output=True)
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout
    return {k: int(v) for k, v in (line.split() for line in out.splitlines())}


def test_record_dtype_and_run_out_match_c_layout(tmp_path):
    c = _c_offsets(tmp_path)
    dt = records.RECORD_DTYPE
    for name in dt.names:
        assert dt.fields[name][1] == c[f"rec.{name}"], name
    assert dt.itemsize == c["rec.size"]
    assert dt["aux"].shape == (compiled.load_layout().NAUX,)
    for name, _ in compiled.RunOut._fields_:
        assert getattr(compiled.RunOut, name).offset == c[f"out.{name}"], name
    assert ctypes.sizeof(compiled.RunOut) == c["out.size"]


def test_merge_orders_by_time_imu_first_and_keeps_input_order():
    imu = records.imu_records([0.0, 0.1, 0.2], np.zeros((3, 3)), np.zeros((3, 3)))
    a = records.measurement_records([0.1, 0.2], 1, [10.0, 11.0], 1.0, sat_id=[7, 7])
    b = records.measurement_records([0.1, 0.05], 0, [20.0, 21.0], 1.0, sat_id=[3, 4])
    merged = records.merge_records(a, imu, b)
    assert list(merged["t"]) == [0.0, 0.05, 0.1, 0.1, 0.1, 0.2, 0.2]
    # at t=0.1: IMU first, then a's record, then b's (argument order)
    assert list(merged["kind"]) == [-1, 0, -1, 1, 0, -1, 1]
    assert list(merged["z"][[3, 4]]) == [10.0, 20.0]
    assert list(merged["sat_id"][[1, 3, 4]]) == [4, 7, 3]
    records.check_records(merged, compiled.load_layout().NMEAS)


def test_imu_records_intervals_and_increments():
    t = np.array([1.0, 1.01, 1.03])
    rec = records.imu_records(t, np.ones((3, 3)) * 2, np.ones((3, 3)) * 3)
    assert np.allclose(rec["dt"], [0.01, 0.01, 0.02])
    L = compiled.load_layout()
    assert np.all(rec["u"][:, L.U_DTHETA_B_SLICE] == 2) and np.all(rec["u"][:, L.U_DVEL_B_SLICE] == 3)
    assert np.all(rec["kind"] == records.KIND_IMU)
    with pytest.raises(ValueError, match="dvel_b"):
        records.imu_records(t, np.zeros((3, 3)), np.zeros((2, 3)))


def test_check_records_names_the_bad_record():
    m = records.measurement_records([0.0, 1.0, 0.5], 0, [1.0, 2.0, 3.0], 1.0)
    with pytest.raises(ValueError, match="record 2: t=0.5"):
        records.check_records(m, 10)
    m = records.measurement_records([0.0, 1.0], 0, [1.0, 2.0], 1.0)
    m["kind"][1] = 42
    with pytest.raises(ValueError, match="record 1: kind 42"):
        records.check_records(m, 10)
