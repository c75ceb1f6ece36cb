"""The bound is right: the generated PCRB recursion equals an independently stacked snapshot CRB."""
from __future__ import annotations

import copy

import numpy as np
import pytest

from leonav_runtime.sweep import crb, montecarlo as mc
from leonav_runtime.scenarios.load import load_scenario, scenario_from_dict


@pytest.fixture(scope="module")
def static_setup():
    raw = copy.deepcopy(load_scenario("paper").raw)
    raw["time"]["duration_s"] = 10.0
    raw["starlink"]["counts"] = [5, 20, 45]
    return mc.setup_for(scenario_from_dict(raw, source="<paper 10 s>"))


@pytest.mark.parametrize("count", [5, 20, 45])
def test_static_pcrb_of_leo_alpha_equals_the_snapshot_crb(static_setup, count):
    setup, nav = static_setup
    S = crb.snapshot_crb(setup, nav, count, "doppler_rate")
    B = crb.pcrb_static(setup, nav, count, "leo-alpha+imu")
    assert np.sqrt(np.trace(B)) == pytest.approx(np.sqrt(np.trace(S)), rel=5e-3)
    assert np.max(np.abs(B - S)) < 1e-2 * np.max(np.abs(S))


def test_more_satellites_give_a_smaller_bound_and_ofdm_is_tighter_than_alpha(static_setup):
    setup, nav = static_setup
    alpha = [np.trace(crb.snapshot_crb(setup, nav, c, "doppler_rate")) for c in (5, 20, 45)]
    assert alpha[0] > alpha[1] > alpha[2]
    ofdm = np.trace(crb.snapshot_crb(setup, nav, 45, "ofdm_range_diff"))
    assert ofdm < alpha[2]


def test_crb_command_with_real_starlink_elements_only(tmp_path, capsys):
    import json

    from leonav_runtime.cli import main
    from tests.conftest import shared_file

    tle = shared_file("tle/starlink_2026-02-23.txt")
    assert main(["crb", "--tle", str(tle), "--out", str(tmp_path)]) == 0
    rows = json.loads((tmp_path / "crb.json").read_text())["rows"]
    crb3d = [r["sqrt_crb_3d_m"] for r in rows]
    assert [r["count"] for r in rows] == list(range(5, 50, 5))
    assert all(a > b for a, b in zip(crb3d, crb3d[1:]))  # more satellites, tighter bound
    for r in rows:  # the filter's PCRB with a vague position prior equals the snapshot CRB
        assert r["sqrt_pcrb_static_3d_m"] == pytest.approx(r["sqrt_crb_3d_m"], rel=5e-3)
    assert "sqrt(CRB) 3D m" in capsys.readouterr().out
