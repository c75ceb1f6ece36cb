"""The time-differenced carrier phase (models/measurements/carrier_phase.py) against a truth
that is not its model (simulation/carrier_truth.py), its orbit Jacobian against finite
differences of a common orbit error, and the filter on it against truth and the PCRB."""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from tests.conftest import short_paper_scenario
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gen import state_layout as L
from leonav_runtime.inputs import SATELLITE_TABLES
from leonav_runtime.scenarios.load import load_scenario
from leonav_runtime.simulation import carrier_truth, front_end
from leonav_runtime.sweep import montecarlo as mc

DRIVE = {"kind": "maneuvers", "attitude_deg": [0.0, 0.0, 90.0], "speed_mps": 15.0,
         "maneuvers": [[4.0, 0.0, 0.0], [6.0, 0.5, 8.0], [6.0, -0.5, -8.0]]}


def _scn(duration_s=16.0, counts=(10,), trajectory=None, position_sigma_m=10.0):
    paper = load_scenario("paper").raw
    sections = {"starlink": {**paper["starlink"], "rate_hz": 10.0},
                "filter": {**paper["filter"], "initial_position_sigma_m": position_sigma_m}}
    if trajectory:
        sections["trajectory"] = trajectory
    return short_paper_scenario(duration_s, list(counts), "<carrier phase test>", modes=("leo-phase+imu",), **sections)


@pytest.fixture(scope="module", params=["static", "drive"])
def prepared(request):
    return mc.setup_for(_scn(trajectory=DRIVE if request.param == "drive" else None))


def test_model_matches_the_exact_light_time_truth(prepared):
    """h at the truth against the exact phase change of the simulator: the second-order receiver
    step, the light-time solution and the Sagnac term of the model must hold to a few um (a
    wrong sign of either is ~1 cycle; leaving out the satellite's start position ~0.04)."""
    setup, nav = prepared
    s = setup.series["carrier_phase"]
    k = np.rint(s.t_s * setup.scn.imu_rate_hz).astype(int)
    h, _ = nav.h_many("carrier_phase", setup.x_true[k], s.aux, jacobian=False)
    assert s.t_s.size > 1000
    assert np.all(np.abs(s.z_true) > 1.0) and np.all(np.abs(s.z_true) < 11.4e9 / 3e8 * 8e3 * 0.1)
    # cycles: 5 um at rest; moving, the receiver's jerk (step changes of acceleration and turn
    # rate here) leaves up to 0.1 mm in the second-order step back, still 1/8 of the noise
    tol = 2e-4 if setup.scn.trajectory["kind"] == "static" else 5e-3
    assert np.max(np.abs(s.z_true - h)) < tol


def test_each_satellite_difference_spans_its_previous_epoch(prepared):
    setup, _ = prepared
    s = setup.series["carrier_phase"]
    assert np.allclose(s.interval_s, 0.1) and np.all(s.k_prev == np.rint((s.t_s - 0.1) * 100).astype(int))
    first = {}
    for t, i in zip(s.t_s, s.sat_id):
        first.setdefault(i, t)
    # no satellite has a difference at the first epoch it was tracked
    dr = setup.series["doppler_rate"]
    for i, t0 in first.items():
        assert t0 > dr.t_s[dr.sat_id == i].min()


def test_front_end_states_enter_as_the_truth_makes_them(prepared):
    """The truth's sample-clock scale and LO integral against the model's s_clk and b_lo terms."""
    setup, nav = prepared
    s = setup.series["carrier_phase"]
    k = np.rint(s.t_s * setup.scn.imu_rate_hz).astype(int)
    n = setup.x_true.shape[0]
    b_lo = 2.0e4 + 3.0 * setup.t_imu            # Hz, drifting 3 Hz/s
    errors = {"b_lo": b_lo.reshape(1, n, 1), "s_clk": np.full((1, n, 1), 80e-6)}
    z = carrier_truth.trial_values(s.z_true, k, s.k_prev, errors, setup.x_true, 1.0 / setup.scn.imu_rate_hz)[0]
    x = setup.x_true[k].copy()
    x[:, L.X_B_LO] = b_lo[k] - 0.5 * 3.0 * s.interval_s    # the interval's mean frequency
    x[:, L.X_S_CLK] = 80e-6
    h, _ = nav.h_many("carrier_phase", x, s.aux, jacobian=False)
    h0, _ = nav.h_many("carrier_phase", setup.x_true[k], s.aux, jacobian=False)
    assert np.max(np.abs((z - h) - (s.z_true - h0))) < 1e-3   # the geometry's own residual aside
    # and they matter: 80 ppm of a 0.1 s interval at tens of kHz is far above the noise
    assert np.max(np.abs(z - s.z_true)) > 100.0


def test_orbit_jacobian_is_that_of_one_orbit_error_at_both_ends(prepared):
    setup, nav = prepared
    s = setup.series["carrier_phase"]
    rows = np.arange(0, s.t_s.size, max(1, s.t_s.size // 40))
    k = np.rint(s.t_s[rows] * setup.scn.imu_rate_hz).astype(int)
    J = nav.orbit_jacobian_many("carrier_phase", setup.x_true[k], s.aux[rows])
    rng = np.random.default_rng(3)
    for _ in range(3):
        dr, dv = rng.normal(size=3) * 50.0, rng.normal(size=3) * 0.05
        aux = s.aux[rows].copy()
        aux[:, L.AUX_R_S_ECEF_SLICE] += dr
        aux[:, L.AUX_V_S_ECEF_SLICE] += dv
        aux[:, L.AUX_R_S_PREV_ECEF_SLICE] += dr - s.interval_s[rows][:, None] * dv
        moved, _ = nav.h_many("carrier_phase", setup.x_true[k], aux, jacobian=False)
        base, _ = nav.h_many("carrier_phase", setup.x_true[k], s.aux[rows], jacobian=False)
        predicted = J[:, 0:3] @ dr + J[:, 3:6] @ dv
        assert np.allclose(moved - base, predicted, rtol=1e-3, atol=2e-3)   # second order: < 0.05 mm


def test_table_without_its_span_is_one_line_naming_the_field():
    table = SATELLITE_TABLES["carrier_phase"](np.zeros(2), np.array([1, 2]), np.zeros(2), 0.04, np.ones((2, 9)))
    with pytest.raises(UserInputError, match="carrier_phase table: interval_s: missing"):
        table.check()
    with pytest.raises(UserInputError, match="sat_prev_r_m"):
        SATELLITE_TABLES["carrier_phase"](np.zeros(2), np.array([1, 2]), np.zeros(2), 0.04, np.ones((2, 9)),
                                          None, 0.1).check()


def test_filter_on_carrier_phase_reaches_its_bound_with_true_orbits():
    """leo-phase+imu, 10 satellites, 16 s at 10 Hz, perfect orbits: the final position error is
    at its sqrt(PCRB) (a model/truth mismatch of 1 mm per epoch leaves a bias many times the
    bound) and the NEES inside a wide band."""
    scn = _scn(position_sigma_m=30.0)
    results = [mc.run_trial(scn, "leo-phase+imu", 10, i) for i in range(6)]
    bound = mc.pcrb_curve(scn, "leo-phase+imu", 10)
    err = np.array([r.err[-1, L.DX_DP_SLICE] for r in results])
    rmse = float(np.sqrt(np.mean(np.sum(err**2, axis=1))))
    sqrt_pcrb = float(bound["position"][-1])   # sqrt(trace) of the position block
    # measured over 20 trials: 1.45 m against 2.23 m, the filter's own covariance on these records
    # (it equals the PCRB there); the errors sit below it, not above: see the issue 22 notes
    assert 0.3 < rmse / sqrt_pcrb < 2.2, (rmse, sqrt_pcrb)
    assert sqrt_pcrb < 0.1 * 30.0           # the phase, not the prior, sets the bound
    nees = np.mean([r.nees[-1] for r in results])
    assert 2.0 < nees < 25.0, nees


# ---- front end (simulation/front_end.py) ---------------------------------------------------

def _front_end(**cfg):
    base = {"enabled": True, "cn0_dbhz": [20.0, 35.0], "pll_bandwidth_hz": 10.0, "lo_phase_noise_dbc_hz": -50.0,
            "lo_phase_noise_offset_hz": 1000.0, "slip_below_dbhz": 25.0, "slip_probability": 0.0,
            "slips_detected": 0.95, "compensate": False}
    return {**base, **cfg}


def _with_front_end(setup, cfg):
    """A copy of the (shared) setup whose scenario has this [front_end] section."""
    scn = copy.copy(setup.scn)
    scn.realism = {**setup.scn.realism, "front_end": cfg}
    out = copy.copy(setup)
    out.scn = scn
    return out


def _carrier_part(setup, cfg):
    s = setup.series["carrier_phase"]
    rows = np.arange(s.t_s.size)
    return s, ["carrier_phase", rows, np.zeros(rows.size), 1e3]   # a nominal sigma no record's exceeds


def test_lo_phase_noise_is_common_to_an_epoch_and_a_wiener_increment(prepared):
    cfg = _front_end()
    setup = _with_front_end(prepared[0], cfg)
    s, part = _carrier_part(setup, cfg)
    front_end.apply(setup, np.random.default_rng(5), part, s)
    z, t = part[2], s.t_s[part[1]]
    epochs = np.unique(t)
    per_epoch = np.array([z[t == e] for e in epochs], dtype=object)
    assert all(np.ptp(v) == 0.0 for v in per_epoch)          # one LO for every tone of the epoch
    first = np.array([v[0] for v in per_epoch])
    expected = math.sqrt(front_end.lo_frequency_psd(cfg) * 0.1 / 2.0)   # cycles over 0.1 s: 1 cycle here
    assert expected == pytest.approx(1.0, rel=1e-9)
    assert np.std(first) == pytest.approx(expected, rel=0.15)
    assert abs(np.corrcoef(first[1:], first[:-1])[0, 1]) < 0.2   # independent from epoch to epoch


def test_weak_tones_slip_and_the_tracker_flags_the_detected_ones(prepared):
    cfg = _front_end(lo_phase_noise_dbc_hz=-200.0, slip_below_dbhz=100.0, slip_probability=1.0, slips_detected=0.5)
    setup = _with_front_end(prepared[0], cfg)
    s, part = _carrier_part(setup, cfg)
    n = part[1].size
    counts = front_end.apply(setup, np.random.default_rng(6), part, s)
    assert counts["slips"] == n and counts["epochs_dropped"] == n - part[1].size
    assert 0.45 < counts["slips_detected"] / n < 0.55
    assert np.allclose(np.abs(part[2]), 1.0, atol=1e-6)      # each kept slip is a whole cycle


def test_record_sigma_follows_the_tones_c_n0_by_elevation(prepared):
    cfg = _front_end(lo_phase_noise_dbc_hz=-200.0)
    setup = _with_front_end(prepared[0], cfg)
    s, part = _carrier_part(setup, cfg)
    part[3] = 1e-6
    elevation = front_end.elevation_rad(setup, part[1], s)
    front_end.apply(setup, np.random.default_rng(7), part, s)
    sigma = part[3]
    high, low = elevation > np.percentile(elevation, 80), elevation < np.percentile(elevation, 20)
    assert sigma[high].mean() < sigma[low].mean()
    # B_n / (C/N0) at the ends of the range, sqrt(2) in a difference (with the 1 ms squaring loss)
    assert front_end.difference_sigma_cyc(35.0, 10.0) == pytest.approx(0.0136, rel=0.01)
    assert front_end.difference_sigma_cyc(20.0, 10.0) == pytest.approx(
        math.sqrt(2 * 10 / 100 * (1 + 1 / 0.2)) / (2 * math.pi), rel=1e-9)
    assert sigma.min() >= front_end.difference_sigma_cyc(35.0, 10.0) - 1e-12
    assert sigma.max() <= front_end.difference_sigma_cyc(20.0, 10.0) + 1e-12


def test_a_zero_orbit_error_leaves_the_exact_phase_truth_unchanged(prepared):
    """The ephemeris realism measures an orbit change through the model against the model at the
    truth, never against the exact truth (that would add the model's own residual to the truth)."""
    from leonav_runtime.simulation import realism

    setup, nav = prepared
    s = setup.series["carrier_phase"]
    rows = np.arange(s.t_s.size)
    zero = {"starlink": {int(i): np.zeros(3) for i in np.unique(s.sat_id)}}
    assert np.all(realism.ephemeris_delta(setup, nav, "carrier_phase", rows, zero) == 0.0)


def test_a_sweep_reports_the_front_ends_slips_and_dropped_epochs(tmp_path):
    """What the front end drops (epochs of detected slips) is counted into metrics.json, per
    (mode, count), summed over the trials: equal to the counts of the trials' own draws."""
    import json

    from leonav_runtime.simulation import simulate
    from leonav_runtime.sweep.run import run_sweep
    paper = load_scenario("paper").raw
    fe = _front_end(slip_below_dbhz=60.0, slip_probability=0.01, slips_detected=0.5)
    scn = short_paper_scenario(4.0, [10], "<slip counts>", modes=("leo-phase+imu",),
                               starlink={**paper["starlink"], "rate_hz": 10.0, "counts": [10]}, front_end=fe)
    run_sweep(scn, tmp_path, trials=3, workers=1, progress=False, figures=False)
    entry = json.loads((tmp_path / "metrics.json").read_text())["results"][0]
    setup, nav = mc.setup_for(scn)
    own = [simulate.trial_records(setup, "leo-phase+imu", 10, mc.trial_rng(scn.seed, i), nav).counts for i in range(3)]
    assert entry["front_end"] == {k: sum(c[k] for c in own) for k in own[0]}
    assert entry["front_end"]["slips"] > 0 and entry["front_end"]["epochs_dropped"] == entry["front_end"]["slips_detected"]
