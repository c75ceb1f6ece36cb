"""leonav_run_out.P_lead: the run loops write only P's leading block when asked (the sweep's NEES
reads the 9D navigation block alone), the same values as the full P's corner."""
from __future__ import annotations

import ctypes

import numpy as np
import pytest

from leonav_runtime.core import compiled
from leonav_runtime.core.filter import EKF
from leonav_runtime.gen import state_layout as L
from leonav_runtime.simulation import simulate
from leonav_runtime.sweep import montecarlo as mc
from tests.conftest import short_paper_scenario

COUNT = 10


def _trial(mode: str, **sections):
    scn = short_paper_scenario(6.0, [COUNT], "<P_lead>", modes=(mode,), **sections)
    setup, nav = mc.setup_for(scn)
    return scn, setup, nav, simulate.trial_records(setup, mode, COUNT, mc.trial_rng(scn.seed, 0), nav)


def _run(case, orbit=None, **kw):
    scn, setup, nav, trial = case
    ekf = EKF(trial.x0, setup.P0, setup.params, gate=scn.filter["gate_nis"], library=nav.library)
    return ekf.run(trial.records, orbit=orbit, **kw)


@pytest.fixture(scope="module")
def paper_case():
    return _trial("gps+leo-doppler+alpha+imu")


@pytest.mark.parametrize("interval", [0.0, 0.1])
@pytest.mark.parametrize("lead", [1, 5, L.NNAV, L.NDX])
def test_the_leading_block_is_the_full_ps_corner_bit_for_bit(paper_case, interval, lead):
    rows = np.arange(3, paper_case[3].records.size, 37)
    full = _run(paper_case, P_rows=rows, covariance_interval_s=interval)
    part = _run(paper_case, P_rows=rows, covariance_interval_s=interval, P_lead=lead)
    assert part.P.shape == (rows.size, lead, lead)
    np.testing.assert_array_equal(part.P, full.P[:, :lead, :lead])
    np.testing.assert_array_equal(part.x, full.x)
    # P after every record (with an interval, each record then ends a covariance run)
    every = _run(paper_case, full_P=True, covariance_interval_s=interval)
    every_part = _run(paper_case, full_P=True, P_lead=lead, covariance_interval_s=interval)
    np.testing.assert_array_equal(every_part.P, every.P[:, :lead, :lead])


def test_the_orbit_state_loop_writes_the_same_leading_block():
    case = _trial("leo-doppler+alpha+imu", ephemeris_error={"enabled": True, "compensate": "states"})
    scn, _, nav, trial = case

    def orbit():
        states = mc.orbit_states_for(scn, trial.records["kind"], nav)
        assert states is not None
        return states

    rows = np.arange(0, trial.records.size, 29)
    full = _run(case, orbit=orbit(), P_rows=rows)
    part = _run(case, orbit=orbit(), P_rows=rows, P_lead=L.NNAV)
    np.testing.assert_array_equal(part.P, full.P[:, :L.NNAV, :L.NNAV])


@pytest.mark.parametrize("bad", [-1, L.NDX + 1, 2.0, True])
def test_a_bad_leading_size_is_refused(paper_case, bad):
    with pytest.raises(ValueError, match="P_lead"):
        _run(paper_case, full_P=True, P_lead=bad)


@pytest.mark.parametrize("bad", [-1, L.NDX + 1])
def test_the_c_loops_refuse_a_leading_size_out_of_range(bad):
    lib = compiled.load()
    x, P, p = np.zeros(L.NX), np.eye(L.NDX), np.zeros(L.NP)
    dp = ctypes.POINTER(ctypes.c_double)
    work = lib.new_workspace()
    for lead, want in ((bad, L.ERR_ARG), (L.NNAV, L.OK)):   # the same call with a good size runs
        out = compiled.RunOut(P_lead=lead)
        rc = lib.lib.leonav_run(x.ctypes.data_as(dp), P.ctypes.data_as(dp), p.ctypes.data_as(dp), None, 0, None, 0.0,
                                ctypes.byref(out), work.ctypes.data)
        assert rc == want


@pytest.mark.parametrize("bad", [-1, L.NDX + 1])
def test_the_orbit_state_loop_refuses_a_leading_size_out_of_range(bad):
    scn, _, nav, trial = _trial("leo-doppler+alpha+imu", ephemeris_error={"enabled": True, "compensate": "states"})
    orbit = mc.orbit_states_for(scn, trial.records["kind"], nav)
    lib = nav.library
    x, P, p = np.zeros(L.NX), np.eye(L.NDX), np.zeros(L.NP)
    dp = ctypes.POINTER(ctypes.c_double)
    work = lib.new_workspace()   # held: the C call must not see a freed temporary
    for lead, want in ((bad, L.ERR_ARG), (L.NNAV, L.OK)):   # the same call with a good size runs
        out = compiled.RunOut(P_lead=lead)
        rc = lib.lib.leonav_run_orbit(x.ctypes.data_as(dp), P.ctypes.data_as(dp), p.ctypes.data_as(dp), None, 0,
                                      None, ctypes.byref(orbit.c), ctypes.byref(out), work.ctypes.data)
        assert rc == want
