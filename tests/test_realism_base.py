"""The simulated base station ([base], ephemeris method 3): its corrections are the orbit
error's effect at its own position, so at the rover's position they remove it and 20 km away
most of it; what they leave is what the filter's inflate-r term is told."""
from __future__ import annotations

import numpy as np
import pytest

from leonav_runtime.scenarios.load import load_scenario
from leonav_runtime.simulation import realism
from leonav_runtime.sweep import montecarlo as mc
from tests.conftest import short_paper_scenario


def _scn(offset_enu_m):
    paper = load_scenario("paper").raw
    sections = {"starlink": {**paper["starlink"], "rate_hz": 10.0},
                "ephemeris_error": {"enabled": True, "element_age_days": 0.25},
                "base": {"enabled": True, "offset_enu_m": list(offset_enu_m)}}
    return short_paper_scenario(6.0, [10], "<base test>", modes=("leo-phase+alpha+imu",), **sections)


@pytest.mark.parametrize("kind", ["carrier_phase", "doppler_rate"])
def test_corrections_remove_the_orbit_error_at_the_base_and_most_of_it_20_km_away(kind):
    rng = np.random.default_rng(4)
    out = {}
    for name, offset in (("here", (0.0, 0.0, 0.0)), ("20 km", (20000.0, 0.0, 0.0))):
        setup, nav = mc.setup_for(_scn(offset))
        rows = np.arange(setup.series[kind].t_s.size)
        errors = realism.draw_orbit_errors(np.random.default_rng(9), setup)
        effect = realism.ephemeris_delta(setup, nav, kind, rows, errors)
        part = [kind, rows, np.zeros(rows.size), 1e-9]     # no base noise: the orbit part alone
        corr = realism.base_corrections(setup, nav, rng, part, errors)
        t = setup.series[kind].t_s[rows]
        _, index = np.unique(t, return_inverse=True)
        left = effect - corr
        left -= (np.bincount(index, left) / np.bincount(index))[index]   # the epoch's common part: the rover's states
        out[name] = (np.sqrt(np.mean(effect**2)), np.sqrt(np.mean(left**2)))
        if name == "20 km":
            sigma = realism.ephemeris_sigma(setup, nav, kind, rows, realism.base_state(setup))
            full = realism.ephemeris_sigma(setup, nav, kind, rows)
            assert np.median(sigma) < 0.2 * np.median(full)
    assert out["here"][1] < 1e-6 * out["here"][0]
    assert out["20 km"][1] < 0.2 * out["20 km"][0]


def test_base_needs_the_orbit_error_it_corrects():
    paper = load_scenario("paper").raw
    with pytest.raises(Exception, match=r"\[base\] enabled = true corrects the orbit error"):
        short_paper_scenario(6.0, [10], "<base test>", base={"enabled": True, "offset_enu_m": [1.0, 0.0, 0.0]},
                             starlink=paper["starlink"])
