"""The standalone C program (hardware/pi, no Python) gives the same run as the Python runtime."""
from __future__ import annotations

import copy
import subprocess

import numpy as np
import pytest

from leonav_runtime.gen.constants import CHI2_1DOF_999
from tests.conftest import pi_program

@pytest.fixture(scope="module")
def program():
    return pi_program()


def _small_run_files(tmp_path, P0=None):
    """A 3 s paper trial's records.bin / init.bin; returns (trial, setup, nav, P0 written)."""
    from leonav_runtime.simulation import simulate
    from leonav_runtime.sweep import montecarlo as mc
    from leonav_runtime.scenarios.load import load_scenario, scenario_from_dict

    raw = copy.deepcopy(load_scenario("paper").raw)
    raw["time"]["duration_s"] = 3.0
    raw["starlink"]["counts"] = [10]
    setup, nav = mc.setup_for(scenario_from_dict(raw, source="<pi test>"))
    trial = simulate.trial_records(setup, "gps+leo-alpha+imu", 10, mc.trial_rng(1, 0), nav)
    P0 = setup.P0 if P0 is None else P0(setup.P0)
    trial.records.tofile(tmp_path / "records.bin")
    np.concatenate([trial.x0, P0.ravel(order="F"), setup.params]).astype("<f8").tofile(tmp_path / "init.bin")
    return trial, setup, nav, P0


def test_standalone_program_matches_the_python_runtime(program, tmp_path):
    from leonav_runtime.core.filter import EKF

    trial, setup, nav, _ = _small_run_files(tmp_path)
    run = subprocess.run([str(program), str(tmp_path / "records.bin"), str(tmp_path / "init.bin"),
                          str(tmp_path / "out.csv")], capture_output=True, text=True)  # default gate
    assert run.returncode == 0, run.stderr
    got = np.genfromtxt(tmp_path / "out.csv", delimiter=",", names=True)
    ref = EKF(trial.x0, setup.P0, setup.params, gate=CHI2_1DOF_999, library=nav.library).run(trial.records)
    L = nav.layout
    x_got = np.column_stack([got[f"x{i}"] for i in range(L.NX)])
    assert got.size == ref.x.shape[0]
    np.testing.assert_array_equal(got["status"].astype(int), ref.status)
    np.testing.assert_allclose(x_got, ref.x, rtol=1e-12, atol=1e-9)
    assert f"{trial.records.size} records" in run.stderr
    # per-observable lines name the observable from the generated table
    n_dr = int(np.sum((ref.kind == L.MEAS_DOPPLER_RATE) & (ref.status == L.STATUS_APPLIED)))
    assert f"DOPPLER_RATE (Hz/s): {n_dr} applied" in run.stderr


def test_standalone_program_names_a_bad_record_kind(program, tmp_path):
    from leonav_runtime.core import records
    from leonav_runtime.gen import state_layout as L

    rec = records.imu_records([0.01, 0.02], np.zeros((2, 3)), np.zeros((2, 3)), dt_s=0.01)
    rec["kind"][1] = L.NMEAS  # not an observable
    rec.tofile(tmp_path / "records.bin")
    P0 = np.eye(L.NDX)
    x0 = np.zeros(L.NX)
    x0[L.X_Q_NB] = 1.0
    np.concatenate([x0, P0.ravel(order="F"), np.zeros(L.NP)]).astype("<f8").tofile(tmp_path / "init.bin")
    run = subprocess.run([str(program), str(tmp_path / "records.bin"), str(tmp_path / "init.bin"),
                          str(tmp_path / "out.csv")], capture_output=True, text=True)
    assert run.returncode == 3 and "LEONAV_ERR_KIND" in run.stderr and "record 1" in run.stderr


def test_standalone_program_rejects_bad_files(program, tmp_path):
    (tmp_path / "r.bin").write_bytes(b"\x00" * 7)
    (tmp_path / "i.bin").write_bytes(b"")
    run = subprocess.run([str(program), str(tmp_path / "r.bin"), str(tmp_path / "i.bin"), str(tmp_path / "o.csv")],
                         capture_output=True, text=True)
    assert run.returncode == 2 and "not a whole number of" in run.stderr


@pytest.mark.parametrize("args, named", [(["abc"], "GATE_NIS"), (["-1"], "GATE_NIS"),
                                         (["10.8", "0.1s"], "COV_INTERVAL"), (["10.8", "nan"], "COV_INTERVAL")])
def test_standalone_program_names_a_bad_number_argument(program, tmp_path, args, named):
    _small_run_files(tmp_path)
    run = subprocess.run([str(program), str(tmp_path / "records.bin"), str(tmp_path / "init.bin"),
                          str(tmp_path / "out.csv"), *args], capture_output=True, text=True)
    assert run.returncode == 2 and named in run.stderr and "expected a finite number" in run.stderr
    assert not (tmp_path / "out.csv").exists()


def test_standalone_program_symmetrizes_P0_as_the_python_runtime(program, tmp_path):
    """The generated steps read P's upper triangle: a P0 given with its triangles apart runs as
    (P0 + P0^T) / 2, the same as the Python EKF (which symmetrizes too)."""
    from leonav_runtime.core.filter import EKF

    def lopsided(P0):
        A = np.array(P0, dtype=float)
        A[0, 1], A[1, 0] = A[0, 1] + 2e-3, A[1, 0] - 1e-3
        A[3, 7] += 1e-4
        return A
    trial, setup, nav, P0 = _small_run_files(tmp_path, lopsided)
    run = subprocess.run([str(program), str(tmp_path / "records.bin"), str(tmp_path / "init.bin"),
                          str(tmp_path / "out.csv"), "0"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    got = np.genfromtxt(tmp_path / "out.csv", delimiter=",", names=True)
    ref = EKF(trial.x0, P0, setup.params, gate=0.0, library=nav.library).run(trial.records)
    L = nav.layout
    x_got = np.column_stack([got[f"x{i}"] for i in range(L.NX)])
    P_got = np.column_stack([got[f"P{i}"] for i in range(L.NDX)])
    np.testing.assert_allclose(x_got, ref.x, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(P_got, ref.P_diag, rtol=1e-9)
