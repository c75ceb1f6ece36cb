"""The PCRB's record stream (montecarlo.pcrb_records): without a realism switch it is the block
template's, which must be a noise-free trial's stream in every field the bound reads and give the
same bound bit for bit; with one, the noise-free trial itself, and no template is built."""
from __future__ import annotations

import numpy as np
import pytest

from leonav_runtime.core import filter as lfilter
from leonav_runtime.scenarios.load import load_scenario
from leonav_runtime.simulation import simulate
from leonav_runtime.sweep import montecarlo as mc
from leonav_runtime.sweep.run import _tasks, build_templates
from tests.conftest import short_paper_scenario


def _noise_free(setup, nav, mode, count) -> np.ndarray:
    return simulate.trial_records(setup, mode, count, np.random.default_rng(0), nav, noise_free=True).records


def _same_but_z(got: np.ndarray, want: np.ndarray, where) -> None:
    assert got.dtype == want.dtype and got.shape == want.shape, where
    for name in want.dtype.names:
        if name != "z":   # byte for byte: signed zeros and NaN payloads too
            assert got[name].tobytes() == want[name].tobytes(), (where, name)


def _local_sensor_scenario():
    """4 s of the paper with a GPS outage and the local sensors (barometer, magnetometer)."""
    return short_paper_scenario(4.0, [5], "<pcrb records: local sensors>",
                                modes=("gps+imu+baro+mag", "leo-alpha+imu+baro"),
                                gps={**load_scenario("paper").raw["gps"], "outages_s": [[1.0, 2.5]]})


@pytest.mark.parametrize("scenario", ["paper", "local sensors", "passive-phase-static"])
def test_pcrb_records_are_the_noise_free_stream_but_for_z(scenario):
    scn = _local_sensor_scenario() if scenario == "local sensors" else load_scenario(scenario)
    setup, nav = mc.setup_for(scn)
    counts = scn.starlink["counts"]
    for mode in scn.modes:
        for count in dict.fromkeys((counts[0], counts[-1])):
            _same_but_z(mc.pcrb_records(setup, nav, mode, count), _noise_free(setup, nav, mode, count), (mode, count))


@pytest.mark.parametrize("mode, count", [("gps+leo-alpha+imu", 45), ("leo-alpha+ofdm+imu", 5)])
def test_pcrb_on_the_template_equals_the_bound_on_the_noise_free_trial(mode, count):
    scn = load_scenario("paper")
    setup, nav = mc.setup_for(scn)
    recs, res = mc.pcrb_on_truth(setup, nav, mode, count)
    want = _noise_free(setup, nav, mode, count)
    k_of = np.rint(want["t"] * scn.imu_rate_hz).astype(int)
    x_lin = setup.x_true[np.where(want["kind"] < 0, k_of - 1, k_of)]
    ref = lfilter.pcrb(want, x_lin, setup.P0, setup.params, library=nav.library)
    assert res.B_nav.tobytes() == ref.B_nav.tobytes() and res.B.tobytes() == ref.B.tobytes()
    assert not np.array_equal(recs["z"], want["z"])   # the template's z are indices, not values
    with pytest.raises(ValueError):   # the trials' template cannot be written through it
        recs["R"][0] = 1.0


def test_a_realism_switch_builds_no_template_for_the_bound_or_the_sweep():
    scn = load_scenario("passive-phase-static")
    setup, nav = mc.setup_for(scn)
    mode, count = scn.modes[0], scn.starlink["counts"][0]
    mc.pcrb_records(setup, nav, mode, count)
    assert build_templates(scn, setup, nav, _tasks(scn, 2)) == 0
    assert not setup.__dict__.get("_block_templates")
    paper = load_scenario("paper")
    p_setup, p_nav = mc.setup_for(paper)
    assert build_templates(paper, p_setup, p_nav, _tasks(paper, 2)) == 46
