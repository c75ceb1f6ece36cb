"""The simulated base station ([base], ephemeris method 3): its corrections are the orbit
error's effect at its own position, so at the rover's position they remove it and 20 km away
most of it; what they leave is what the filter's inflate-r term is told."""
from __future__ import annotations

import numpy as np
import pytest

from leonav_runtime.inputs import consider
from leonav_runtime.scenarios.load import load_scenario
from leonav_runtime.simulation import base_station, orbit_truth, realism
from leonav_runtime.sweep import montecarlo as mc
from tests.conftest import short_paper_scenario


def _scn(offset_enu_m, duration_s=6.0, corrections="measurement", compensate="inflate-r", correlation_s=0.0):
    paper = load_scenario("paper").raw
    sections = {"starlink": {**paper["starlink"], "rate_hz": 10.0},
                "ephemeris_error": {"enabled": True, "element_age_days": 0.25, "compensate": compensate,
                                    "consider_correlation_s": correlation_s},
                "base": {"enabled": True, "offset_enu_m": list(offset_enu_m), "corrections": corrections}}
    return short_paper_scenario(duration_s, [10], "<base test>", modes=("leo-phase+alpha+imu",), **sections)


def _epoch_demeaned(t, x):
    _, index = np.unique(t, return_inverse=True)
    return x - (np.bincount(index, x) / np.bincount(index))[index]


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
        corr = base_station.base_corrections(setup, nav, rng, part, errors)
        t = setup.series[kind].t_s[rows]
        _, index = np.unique(t, return_inverse=True)
        left = effect - corr
        left -= (np.bincount(index, left) / np.bincount(index))[index]   # the epoch's common part: the rover's states
        out[name] = (np.sqrt(np.mean(effect**2)), np.sqrt(np.mean(left**2)))
        if name == "20 km":
            sigma = realism.ephemeris_sigma(setup, nav, kind, rows, orbit_truth.base_state(setup))
            full = realism.ephemeris_sigma(setup, nav, kind, rows)
            assert np.median(sigma) < 0.2 * np.median(full)
    assert out["here"][1] < 1e-6 * out["here"][0]
    assert out["20 km"][1] < 0.2 * out["20 km"][0]


def test_base_needs_the_orbit_error_it_corrects():
    paper = load_scenario("paper").raw
    with pytest.raises(Exception, match=r"\[base\] enabled = true corrects the orbit error"):
        short_paper_scenario(6.0, [10], "<base test>", base={"enabled": True, "offset_enu_m": [1.0, 0.0, 0.0]},
                             starlink=paper["starlink"])


@pytest.mark.parametrize("kind, left_share", [("carrier_phase", 0.05), ("doppler_rate", 0.2)])
def test_orbit_corrections_take_the_orbit_error_out_20_km_away(kind, left_share):
    """The base's fitted offsets (20 s of its own rows) against the drawn ones: within their
    covariance, and the rover's rows with its satellites moved by them keep a few % of the
    orbit error's effect (measured: 1 % for the phase, 6 % for the Doppler-rate)."""
    setup, nav = mc.setup_for(_scn((20000.0, 0.0, 0.0), 20.0, "orbit"))
    s = setup.series[kind]
    rows = np.flatnonzero(s.rank < 10)
    errors = realism.draw_orbit_errors(np.random.default_rng(9), setup)
    sigma = {"carrier_phase": setup.scn.starlink["carrier_phase_sigma_cyc"],
             "doppler_rate": setup.scn.starlink["doppler_rate_sigma_hz_s"]}[kind]
    fit = base_station.orbit_fit(setup, nav, np.random.default_rng(3), [[kind, rows, np.zeros(rows.size), sigma]],
                                 errors)
    err = fit.offsets_rac_m[-1] - orbit_truth.offsets(errors["starlink"], fit.sat_ids)
    sd = np.sqrt(np.einsum("nii->ni", fit.cov_rac_m2[-1]))
    assert np.all((0.5 < np.sqrt(np.mean((err / sd) ** 2, axis=0))) & (np.sqrt(np.mean((err / sd) ** 2, axis=0)) < 2.0))
    effect = orbit_truth.ephemeris_delta(setup, nav, kind, rows, errors)
    served = {"starlink": dict(zip(fit.sat_ids.tolist(), fit.offsets_rac_m[-1]))}
    left = effect - orbit_truth.ephemeris_delta(setup, nav, kind, rows, served)
    last = s.t_s[rows] > 15.0
    rms = [np.sqrt(np.mean(_epoch_demeaned(s.t_s[rows], x)[last] ** 2)) for x in (effect, left)]
    assert rms[1] < left_share * rms[0]


def test_the_rover_flies_the_served_orbits():
    """base_station.apply in orbit mode: each row's satellite states are moved by the offsets
    served at or before its epoch, closer to the true orbit than the element orbit is; R grows
    by what the served covariance does to the row."""
    setup, nav = mc.setup_for(_scn((20000.0, 0.0, 0.0), 20.0, "orbit"))
    kind = "carrier_phase"
    s = setup.series[kind]
    rows = np.flatnonzero(s.rank < 10)
    errors = realism.draw_orbit_errors(np.random.default_rng(9), setup)
    sigma = setup.scn.starlink["carrier_phase_sigma_cyc"]
    part = [kind, rows, np.zeros(rows.size), sigma]
    base_station.apply(setup, nav, np.random.default_rng(3), [part], errors)   # inflate-r (_scn)
    sat9, prev = part[4]
    true9 = orbit_truth.perturb_states(s.sat_ecef[rows], orbit_truth.offsets(errors["starlink"], s.sat_id[rows]))
    late = s.t_s[rows] > 15.0
    moved_off = np.linalg.norm(sat9[late, 0:3] - true9[late, 0:3], axis=1)
    element_off = np.linalg.norm(s.sat_ecef[rows][late, 0:3] - true9[late, 0:3], axis=1)
    assert np.median(moved_off) < 0.2 * np.median(element_off)
    assert prev is not None and prev.shape == (rows.size, 3)
    assert np.all(part[3] > sigma) and np.median(part[3][late]) < np.median(part[3][~late])   # the fit's covariance shrinks


def test_under_consider_the_served_covariance_is_shared_by_a_satellites_records():
    """compensate = "consider" with orbit corrections: a record's R grows by m times what the
    served covariance does to it (m: its satellite's records within the correlation time), and
    the road's consider term leaves the corrected kinds alone (no element-set term on top)."""
    grown = {}
    for compensate, corr in (("inflate-r", 0.0), ("consider", 2.0)):
        setup, nav = mc.setup_for(_scn((20000.0, 0.0, 0.0), 6.0, "orbit", compensate, corr))
        s = setup.series["carrier_phase"]
        rows = np.flatnonzero(s.rank < 10)
        errors = realism.draw_orbit_errors(np.random.default_rng(9), setup)
        part = ["carrier_phase", rows, np.zeros(rows.size), 0.01]
        base_station.apply(setup, nav, np.random.default_rng(3), [part], errors)
        grown[compensate] = part[3] ** 2 - 0.01**2
        if compensate == "consider":
            kinds = realism.orbit_consider(setup.scn).sigma_rac_m
            assert "carrier_phase" not in kinds and "doppler_rate" not in kinds and "ofdm_range_diff" in kinds
            m = consider.records_per_satellite(s.sat_id[rows], s.t_s[rows], 2.0)
    assert np.all(m > 1) and np.allclose(grown["consider"], m * grown["inflate-r"], rtol=1e-9)
