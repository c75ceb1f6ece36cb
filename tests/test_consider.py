"""Consider (Schmidt) term of ephemeris error: the generated orbit Jacobian, P_sat, R_eff."""
from __future__ import annotations

import copy

import numpy as np
import pytest

from leonav_runtime.sweep import montecarlo as mc
from leonav_runtime.simulation import realism, simulate
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gen import state_layout as L
from leonav_runtime.inputs import consider
from leonav_runtime.inputs.measurements import states_from_aux
from leonav_runtime.scenarios.load import load_scenario, scenario_from_dict

ORBIT_COLS = (L.AUX_R_S_ECEF_SLICE, L.AUX_V_S_ECEF_SLICE, L.AUX_R_REF_ECEF_SLICE, L.AUX_V_REF_ECEF_SLICE)


def _scn(duration_s=3.0, count=10, **eph):
    raw = copy.deepcopy(load_scenario("paper").raw)
    raw["time"]["duration_s"] = duration_s
    raw["starlink"]["counts"] = [count]
    raw["monte_carlo"]["modes"] = ["leo-alpha+imu"]
    raw["ephemeris_error"] = dict(eph)
    return scenario_from_dict(raw, source="<consider test>")


@pytest.fixture(scope="module")
def geometry():
    """Truth states and aux rows of the paper run's Doppler-rate records (10 satellites, 3 s),
    with the ref block filled from another satellite so the OFDM difference has a reference."""
    setup, nav = mc.setup_for(_scn())
    s = setup.series["doppler_rate"]
    rows = simulate.selected_rows(setup, "doppler_rate", 10)
    k = np.rint(s.t_s[rows] * setup.scn.imu_rate_hz).astype(int)
    aux = s.aux[rows].copy()
    aux[:, L.AUX_R_REF_ECEF_SLICE.start:L.AUX_A_REF_ECEF_SLICE.stop] = np.roll(s.sat_ecef[rows], 3, axis=0)
    return setup, nav, setup.x_true[k], aux


@pytest.mark.parametrize("kind", ["doppler_rate", "doppler", "ofdm_range_diff", "pseudorange"])
def test_generated_orbit_jacobian_matches_finite_differences_of_generated_h(geometry, kind):
    setup, nav, x, aux = geometry
    J = nav.orbit_jacobian_many(kind, x, aux, setup.params)
    assert J.shape == (aux.shape[0], L.NORBIT) and np.all(np.isfinite(J))
    col = 0
    for block, step in zip(ORBIT_COLS, (1.0, 1e-3, 1.0, 1e-3)):   # m, m/s: central differences
        for c in range(block.start, block.stop):
            up, dn = aux.copy(), aux.copy()
            up[:, c] += step
            dn[:, c] -= step
            fd = (nav.h_many(kind, x, up, setup.params, jacobian=False)[0]
                  - nav.h_many(kind, x, dn, setup.params, jacobian=False)[0]) / (2 * step)
            scale = np.abs(J[:, col - col % 3:col - col % 3 + 3]).max() + 1e-300
            assert np.abs(J[:, col] - fd).max() <= 1e-5 * scale, (kind, col)
            col += 1
    # which blocks an observable reads: alpha and Doppler only the satellite, OFDM also the reference
    reads_ref = kind == "ofdm_range_diff"
    assert np.any(J[:, 6:9] != 0) == reads_ref and np.all(J[:, 9:12] == 0)
    assert np.any(J[:, 3:6] != 0) == (kind in ("doppler_rate", "doppler"))


def test_generated_orbit_jacobian_equals_the_symbolic_model(geometry):
    ca = pytest.importorskip("casadi", reason="the symbolic models need casadi")
    from leonav.models.measurements import models
    from leonav.models.measurements.orbit_jacobian import orbit_jacobian
    from leonav.models.state import NAUX, NP, NX

    setup, nav, x, aux = geometry
    xs, auxs, ps = ca.SX.sym("x", NX), ca.SX.sym("aux", NAUX), ca.SX.sym("p", NP)
    for kind in ("doppler_rate", "ofdm_range_diff"):
        f = ca.Function("j", [xs, auxs, ps], [orbit_jacobian(models()[kind](xs, auxs, ps), auxs)])
        J = nav.orbit_jacobian_many(kind, x, aux, setup.params)
        for i in (0, aux.shape[0] // 2, aux.shape[0] - 1):
            ref = np.asarray(f(x[i], aux[i], setup.params)).ravel()
            assert J[i] == pytest.approx(ref, rel=1e-9, abs=1e-12 * np.abs(ref).max())


def test_orbit_jacobian_of_a_kind_without_one_is_refused(geometry):
    setup, nav, x, aux = geometry
    with pytest.raises(RuntimeError, match="ERR_KIND"):
        nav.orbit_jacobian_many("pos_e", x, aux, setup.params)


def test_orbit_covariance_is_the_linearised_truth_model():
    """G maps radial/along/cross offsets to what realism.perturb_states does, to first order."""
    r = np.array([6928e3, 0.0, 0.0])
    v = np.array([0.0, 7590.0 * np.cos(0.93), 7590.0 * np.sin(0.93)])
    a = -3.986004418e14 * r / np.linalg.norm(r) ** 3
    state = np.concatenate([r, v, a])[None, :]
    G = consider.orbit_error_map(state)[0]
    for axis in range(3):
        d = np.zeros((1, 3))
        d[0, axis] = 1.0   # 1 m: the second-order terms are ~1e-7 of it
        moved = realism.perturb_states(state, d)[0]
        assert moved[:6] - state[0, :6] == pytest.approx(G[:, axis], abs=1e-6)
    # the time shift's velocity error is radial, ~ n sigma_A (mean motion n)
    n = np.sqrt(3.986004418e14 / np.linalg.norm(r) ** 3)
    assert np.linalg.norm(G[3:6, 1]) == pytest.approx(n, rel=1e-3)
    P = consider.orbit_covariance(state, [240.0, 960.0, 170.0])[0]
    assert np.allclose(P, P.T) and np.linalg.eigvalsh(P).min() > -1e-6
    assert np.sqrt(np.trace(P[:3, :3])) == pytest.approx(np.linalg.norm([240.0, 960.0, 170.0]), rel=1e-9)


def test_consider_variance_equals_monte_carlo_spread_of_alpha(geometry):
    """sqrt(J P_sat J^T) = the spread of alpha (generated h) over sampled orbit errors of the
    satellite (perturb_states, the simulator's truth model), per record."""
    setup, nav, x, aux = geometry
    rows = np.arange(0, aux.shape[0], max(1, aux.shape[0] // 6))   # a few geometries
    x, aux = x[rows], aux[rows]
    sat9, _ = states_from_aux(aux, L)
    sig = np.array([240.0, 960.0, 170.0]) * 4.0       # a 1 d old element set: still linear
    J = nav.orbit_jacobian_many("doppler_rate", x, aux, setup.params)
    predicted = np.sqrt(consider.consider_variance(J, sat9, None, sig))
    rng = np.random.default_rng(11)
    n_mc = 3000
    base = nav.h_many("doppler_rate", x, aux, setup.params, jacobian=False)[0]
    d = rng.standard_normal((n_mc, rows.size, 3)) * sig
    moved = np.repeat(aux[None], n_mc, axis=0)
    moved[:, :, 0:9] = realism.perturb_states(np.tile(sat9, (n_mc, 1)), d.reshape(-1, 3)).reshape(n_mc, rows.size, 9)
    h = nav.h_many("doppler_rate", np.tile(x, (n_mc, 1)), moved.reshape(-1, L.NAUX), setup.params, jacobian=False)[0]
    spread = np.std(h.reshape(n_mc, rows.size) - base, axis=0)
    assert predicted.min() > 0.5                                    # Hz/s: a real effect, not noise
    assert spread == pytest.approx(predicted, rel=0.05)             # 3000 draws: ~1.3 % standard error


def test_consider_adds_j_p_jt_to_r_on_the_input_road():
    base = _records(_scn(), 0)
    comp = _records(_scn(compensate="consider"), 0)
    setup, nav = mc.setup_for(_scn())
    alpha = base.records["kind"] == nav.kind_id("doppler_rate")
    assert base.records["z"].tobytes() == comp.records["z"].tobytes()       # the filter only
    extra = comp.records["R"][alpha] - base.records["R"][alpha]
    aux = base.records["aux"][alpha]
    sat9, _ = states_from_aux(aux, L)
    J = nav.orbit_jacobian_many("doppler_rate", base.x0, aux, setup.params)   # at the prior
    sig = realism.starlink_sigma_rac(_scn(compensate="consider").realism["ephemeris"])
    assert extra == pytest.approx(consider.consider_variance(J, sat9, None, sig), rel=1e-12)
    # correlated: each record's term times the records of its satellite within the time
    corr = _records(_scn(compensate="consider", consider_correlation_s=2.0), 0)
    m = consider.records_per_satellite(base.records["sat_id"][alpha], base.records["t"][alpha], 2.0)
    assert set(np.unique(m)) >= {2.0, 3.0}
    assert corr.records["R"][alpha] - base.records["R"][alpha] == pytest.approx(extra * m, rel=1e-12)


def _records(scn, index):
    setup, nav = mc.setup_for(scn)
    return simulate.trial_records(setup, "leo-alpha+imu", 10, mc.trial_rng(scn.seed, index), nav)


def test_consider_brings_nees_closer_to_its_band_than_no_compensation():
    """Orbit errors of a 3 d old element set, 8 trials of 4 s: NEES far above its band without
    compensation, at most a quarter as far (log scale) with the consider term."""
    def distance(comp):
        scn = _scn(duration_s=4.0, count=10, enabled=True, element_age_days=3.0, compensate=comp)
        res = [mc.run_trial(scn, "leo-alpha+imu", 10, i) for i in range(8)]
        s = mc.summarize(res, {name: np.ones(res[0].err.shape[0]) for name in mc.BLOCKS})["nees"]
        lo, hi = s["band95"]
        return max(0.0, np.log(s["mean"] / hi), np.log(lo / s["mean"]))
    off, on = distance("none"), distance("consider")
    assert off > 1.0                                                     # > e times the band's top
    assert on <= 0.25 * off


def test_consider_with_correlation_time_puts_nees_in_its_band_where_white_does_not():
    """45 satellites, 10 s, 6 h old elements: white consider leaves NEES above the band (the
    error is shared by a satellite's records); scaling by the records per satellite brings it in."""
    def nees(corr):
        scn = _scn(duration_s=10.0, count=45, enabled=True, compensate="consider", consider_correlation_s=corr)
        res = [mc.run_trial(scn, "leo-alpha+imu", 45, i) for i in range(10)]
        return mc.summarize(res, {name: np.ones(res[0].err.shape[0]) for name in mc.BLOCKS})["nees"]
    white, corr = nees(0.0), nees(600.0)
    assert white["mean"] > white["band95"][1]
    assert corr["band95"][0] <= corr["mean"] <= corr["band95"][1]


@pytest.mark.parametrize("value, fragment", [("schmidt", "compensate"), (-1.0, "consider_correlation_s")])
def test_bad_consider_values_name_the_field(value, fragment):
    key = "compensate" if fragment == "compensate" else "consider_correlation_s"
    with pytest.raises(UserInputError, match=fragment):
        _scn(**{key: value})
