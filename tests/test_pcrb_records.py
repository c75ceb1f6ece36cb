"""The PCRB runs on the block template's records (montecarlo.pcrb_records): they must be a
noise-free trial's stream in every field the bound reads, and give the same bound bit for bit."""
from __future__ import annotations

import numpy as np
import pytest

from leonav_runtime.core import filter as lfilter
from leonav_runtime.scenarios.load import load_scenario
from leonav_runtime.simulation import simulate
from leonav_runtime.sweep import montecarlo as mc


def _noise_free(setup, nav, mode, count) -> np.ndarray:
    return simulate.trial_records(setup, mode, count, np.random.default_rng(0), nav, noise_free=True).records


@pytest.mark.parametrize("scenario", ["paper", "passive-phase-static"])
def test_pcrb_records_are_the_noise_free_stream_but_for_z(scenario):
    scn = load_scenario(scenario)
    setup, nav = mc.setup_for(scn)
    counts = scn.starlink["counts"]
    for mode in scn.modes:
        for count in (counts[0], counts[-1]):
            want, got = _noise_free(setup, nav, mode, count), mc.pcrb_records(setup, nav, mode, count)
            assert got.dtype == want.dtype and got.shape == want.shape, (mode, count)
            for name in want.dtype.names:
                if name != "z":
                    assert np.array_equal(got[name], want[name], equal_nan=True), (mode, count, name)


@pytest.mark.parametrize("mode, count", [("gps+leo-alpha+imu", 45), ("leo-alpha+ofdm+imu", 5)])
def test_pcrb_on_the_template_equals_the_bound_on_the_noise_free_trial(mode, count):
    scn = load_scenario("paper")
    setup, nav = mc.setup_for(scn)
    recs, res = mc.pcrb_on_truth(setup, nav, mode, count)
    want = _noise_free(setup, nav, mode, count)
    k_of = np.rint(want["t"] * scn.imu_rate_hz).astype(int)
    x_lin = setup.x_true[np.where(want["kind"] < 0, k_of - 1, k_of)]
    ref = lfilter.pcrb(want, x_lin, setup.P0, setup.params, library=nav.library)
    assert np.array_equal(res.B_nav, ref.B_nav) and np.array_equal(res.B, ref.B)
    assert not np.array_equal(recs["z"], want["z"])   # the template's z are indices, not values
    with pytest.raises(ValueError):   # the trials' template cannot be written through it
        recs["R"][0] = 1.0
