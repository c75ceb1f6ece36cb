"""Realism switches term by term: each unmodelled error has the closed form it claims."""
from __future__ import annotations

import copy

import numpy as np
import pytest

from leonav_runtime import montecarlo as mc
from leonav_runtime import realism, simulate
from leonav_runtime.gen import state_layout as L
from leonav_runtime.scenario import load_scenario, scenario_from_dict

PAPER_MODES = load_scenario("paper").raw["monte_carlo"]["modes"]


def _scn(modes=("gps+imu", "leo-alpha+imu"), duration_s=3.0, **sections):
    raw = copy.deepcopy(load_scenario("paper").raw)
    raw["time"]["duration_s"] = duration_s
    raw["starlink"]["counts"] = [10]
    raw["monte_carlo"]["modes"] = list(modes)
    raw.update(copy.deepcopy(sections))
    return scenario_from_dict(raw, source="<realism term test>")


def test_every_paper_mode_runs_with_the_ephemeris_error_on():
    on = _scn(modes=PAPER_MODES, duration_s=2.0, ephemeris_error={"enabled": True, "compensate": "inflate-r",
                                                                      "apply_to": ["starlink", "gps"]})
    off = _scn(modes=PAPER_MODES, duration_s=2.0)
    setup, nav = mc.setup_for(on)
    for mode in PAPER_MODES:
        a = simulate.trial_records(setup, mode, 10, mc.trial_rng(on.seed, 0), nav)
        b = simulate.trial_records(mc.setup_for(off)[0], mode, 10, mc.trial_rng(off.seed, 0), nav)
        sat = a.records["kind"] >= 0
        assert np.all(np.isfinite(a.records["z"][sat])), mode
        # every satellite observable of the mode moved (GPS by metres, Starlink ones by their orbit error)
        for kind in np.unique(a.records["kind"][sat]):
            k = a.records["kind"] == kind
            assert np.any(a.records["z"][k] != b.records["z"][k]), (mode, kind)
            assert np.all(a.records["R"][k] > b.records["R"][k]), (mode, kind)


def test_ofdm_reference_is_the_epochs_highest_satellite():
    setup, nav = mc.setup_for(_scn(modes=["leo-ofdm+imu"], duration_s=2.0))
    rows = simulate.selected_rows(setup, "ofdm_range_diff", 10)
    ids = realism._ref_ids(setup, "ofdm_range_diff", rows)
    s, dr = setup.series["ofdm_range_diff"], setup.series["doppler_rate"]
    for t, i, ref_state in zip(s.t_s[rows], ids, s.ref_ecef[rows]):
        top = (dr.t_s == t) & (dr.rank == 0)
        assert dr.sat_id[top] == [i] and np.array_equal(dr.sat_ecef[top][0], ref_state)
