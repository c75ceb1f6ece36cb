"""Ephemeris method 1 as a filter (csrc/leonav_orbit_states.c, core/orbit_states.py): the C move
of a satellite by its offsets is the simulator's orbit-truth move; the augmented filter equals a
NumPy filter written from the textbook (dense augmented covariance, the generated predict and h,
central differences over the moved aux) record for record; slots run out and are reused as
documented; and on a run whose truth has orbit errors it beats the consider term and estimates
the along-track errors."""
from __future__ import annotations

import copy

import numpy as np
import pytest

from tests.conftest import orbit_phase_stream
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.core import filter as lfilter
from leonav_runtime.core import navfuncs, orbit_states
from leonav_runtime.scenarios.load import load_scenario, scenario_from_dict
from leonav_runtime.simulation.orbit_truth import move_aux
from leonav_runtime.sweep.run import run_sweep

MODE = "leo-phase+alpha+imu"


@pytest.fixture(scope="module")
def stream():
    return orbit_phase_stream(6.0, 6, MODE)


def test_the_c_move_is_the_orbit_truths_move(stream):
    setup, nav, recs, _ = stream
    rng = np.random.default_rng(1)
    for kind in orbit_states.offset_kinds() & set(np.unique(recs["kind"]).tolist()):
        aux = recs["aux"][recs["kind"] == kind][:40]
        d = rng.normal(0.0, [240.0, 960.0, 170.0], (aux.shape[0], 3))
        np.testing.assert_allclose(orbit_states.move_aux(nav.library.lib, aux, d), move_aux(aux, d, nav.layout),
                                   rtol=0, atol=1e-7)


def _reference(recs, x0, P0, params, nav, n_slots, prior_sigma, gate):
    """The augmented filter in NumPy: the state [dx | offsets of the satellites in slots]."""
    L = nav.layout
    ndx = int(L.NDX)
    predict = navfuncs.GeneratedFunction(nav.library.lib, "leonav_predict")
    kinds = orbit_states.offset_kinds()
    x, m = np.array(x0, float), 3 * n_slots
    P = np.zeros((ndx + m, ndx + m))
    P[:ndx, :ndx] = P0
    off = np.zeros(m)
    slots: dict[int, int] = {}
    for r in recs:
        if r["kind"] < 0:
            x_n, P_n, F, _ = predict(x, P[:ndx, :ndx], r["u"], float(r["dt"]), params)
            x = x_n[:, 0]
            P[:ndx, ndx:] = F @ P[:ndx, ndx:]
            P[ndx:, :ndx] = P[:ndx, ndx:].T
            P[:ndx, :ndx] = P_n
            continue
        H = np.zeros(ndx + m)
        aux = r["aux"][None]
        if int(r["kind"]) in kinds:
            s = int(r["sat_id"])
            if s not in slots:
                j = slots[s] = len(slots)
                c = ndx + 3 * j
                P[c:c + 3, c:c + 3] = np.diag(np.asarray(prior_sigma) ** 2)
            j = slots[s]
            d = off[3 * j:3 * j + 3]
            h, H[:ndx] = nav.h(int(r["kind"]), x, move_aux(aux, d[None], L)[0])
            for a in range(3):
                e = np.eye(3)[a]
                hp = nav.h(int(r["kind"]), x, move_aux(aux, (d + e)[None], L)[0])[0]
                hm = nav.h(int(r["kind"]), x, move_aux(aux, (d - e)[None], L)[0])[0]
                H[ndx + 3 * j + a] = (hp - hm) / 2.0
        else:
            h, H[:ndx] = nav.h(int(r["kind"]), x, r["aux"])
        y = r["z"] - h
        b = P @ H
        S = H @ b + r["R"]
        if y * y / S > gate:
            continue
        K = b / S
        x = nav.boxplus(x, K[:ndx] * y)
        off += K[ndx:] * y
        P -= np.outer(b, b) / S
    return x, P, off, slots


def test_the_c_filter_is_the_textbook_augmented_filter(stream):
    setup, nav, recs, x_lin = stream
    rng = np.random.default_rng(7)
    noisy = recs.copy()
    meas = noisy["kind"] >= 0
    noisy["z"][meas] += rng.standard_normal(int(meas.sum())) * np.sqrt(noisy["R"][meas])
    x0 = nav.boxplus(x_lin[0], rng.normal(0, 1, int(nav.layout.NDX)) * np.sqrt(np.diag(setup.P0)))
    sigma = [240.0, 960.0, 170.0]
    orbit = orbit_states.OrbitStates(nav.layout.NDX, len(nav.library.meas_ids), 8, sigma)
    ekf = lfilter.EKF(x0, setup.P0, setup.params, gate=10.83, library=nav.library)
    res = ekf.run(noisy, orbit=orbit)
    x_ref, P_ref, off_ref, slots = _reference(noisy, x0, setup.P0, setup.params, nav, 8, sigma, 10.83)
    ndx = int(nav.layout.NDX)
    assert orbit.counts == {"slots_taken": len(slots), "slots_reused": 0, "no_slot": 0} and len(slots) == 6
    assert res.n_applied > 0.95 * meas.sum()
    order = [slots[s] for s in orbit.slot_sat.tolist() if s >= 0]   # C slot j holds the j-th satellite too
    assert order == list(range(len(slots)))
    # A phase update removes most of a 10 m prior's variance at once (S is 1e-5 of H P H^T), so the
    # two roundings part by more than 1e-9 in absolute terms; measured against the sigmas they agree
    # to < 1e-3 (the C's expanded Joseph form against P - b b^T / S here).
    m = 3 * len(slots)
    sig_x = np.sqrt(np.diag(P_ref[:ndx, :ndx]))
    used = sig_x > 0
    sig_o = np.sqrt(np.diag(P_ref[ndx:ndx + m, ndx:ndx + m]))
    assert np.max(np.abs(nav.boxminus(ekf.x, x_ref)[used] / sig_x[used])) < 1e-3
    assert np.max(np.abs(orbit.offset[:m] - off_ref[:m]) / sig_o) < 1e-3
    np.testing.assert_allclose(np.sqrt(np.diag(ekf.P))[used], sig_x[used], rtol=1e-3)
    cov = orbit.offset_covariance()[:m, :m]
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), sig_o, rtol=1e-3)
    np.testing.assert_allclose(cov / np.outer(sig_o, sig_o), P_ref[ndx:ndx + m, ndx:ndx + m] / np.outer(sig_o, sig_o),
                               atol=1e-3)   # and every correlation between offsets
    assert not np.any(np.tril(orbit.P_oo, -1))   # the C writes one triangle (column-major lower)
    corr = P_ref[:ndx, ndx:ndx + m][used] / np.outer(sig_x[used], sig_o)   # cross-covariance as correlations
    np.testing.assert_allclose(orbit.P_no[:m].T[used] / np.outer(sig_x[used], sig_o), corr, atol=1e-3)
    # the offsets are information: they do not leave the prior's sigmas unchanged
    assert np.all(np.sqrt(np.diag(cov)) < np.tile(sigma, len(slots)))


def test_slots_run_out_and_are_reused_after_free_after(stream):
    setup, nav, recs, x_lin = stream
    L = nav.layout
    few = orbit_states.OrbitStates(L.NDX, len(nav.library.meas_ids), 3, [100.0, 100.0, 100.0])
    res = lfilter.EKF(x_lin[0], setup.P0, setup.params, library=nav.library).run(recs, orbit=few)
    kinds = np.isin(recs["kind"], sorted(orbit_states.offset_kinds()))
    other_sats = kinds & ~np.isin(recs["sat_id"], few.slot_sat)
    assert few.counts["no_slot"] == int(other_sats.sum()) > 0 and few.counts["slots_reused"] == 0
    assert np.all(res.status[other_sats] == lfilter.STATUS_FAILED)
    # a short free_after: a satellite of the first second gives its slot away once gone that long
    first = recs[recs["t"] <= 1.0]
    late = recs[recs["t"] > 1.0].copy()
    late["sat_id"][np.isin(late["kind"], sorted(orbit_states.offset_kinds()))] += 1000   # "new" satellites
    stream2 = np.concatenate([first, late[late["t"] > 1.5]])
    reuse = orbit_states.OrbitStates(L.NDX, len(nav.library.meas_ids), 6, [100.0, 100.0, 100.0], free_after_s=0.3)
    lfilter.EKF(x_lin[0], setup.P0, setup.params, library=nav.library).run(stream2, orbit=reuse)
    assert reuse.counts["slots_reused"] == 6 and reuse.counts["no_slot"] == 0
    assert set(reuse.slot_sat.tolist()) == set(np.unique(late["sat_id"][late["sat_id"] >= 1000]).tolist())


def test_bad_arguments_are_refused(stream):
    setup, nav, recs, x_lin = stream
    L = nav.layout
    with pytest.raises(ValueError, match="n_slots"):
        orbit_states.OrbitStates(L.NDX, len(nav.library.meas_ids), 0, [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="prior sigmas"):
        orbit_states.OrbitStates(L.NDX, len(nav.library.meas_ids), 4, [1.0, 0.0, 1.0])
    cv = recs[:3].copy()
    cv["kind"][0] = L.KIND_CV
    orbit = orbit_states.OrbitStates(L.NDX, len(nav.library.meas_ids), 4, [1.0, 1.0, 1.0])
    with pytest.raises(RuntimeError, match="leonav_run_orbit returned LEONAV_ERR_KIND at record 0"):
        lfilter.EKF(x_lin[0], setup.P0, setup.params, library=nav.library).run(cv, orbit=orbit)


def _static(compensate: str, **eph):
    raw = copy.deepcopy(load_scenario("passive-phase-static").raw)
    raw["time"]["duration_s"] = 40.0
    raw["starlink"]["counts"] = [10]
    raw["monte_carlo"].update(trials=6, modes=["leo-phase+imu"])
    raw["front_end"]["enabled"] = False
    raw["ephemeris_error"].update(compensate=compensate, **eph)
    return scenario_from_dict(raw, source=f"<passive-phase-static, {compensate}>")


def test_on_orbit_errors_the_states_beat_the_consider_term_and_stay_consistent():
    """40 s static, 10 satellites, element sets 6 h old in the truth (~1 km along track): with
    each satellite's offsets as states the velocity error falls from 9.1 to 0.67 m/s and the
    final position error from 222 to 130 m (6 trials; the bound of method 1 is 56 m at 60 s on
    the 5 min run), with the NEES inside its band; every satellite found a slot."""
    out = {}
    for c in ("consider", "states"):
        res = run_sweep(_static(c), None, workers=1, progress=False, figures=False)
        out[c] = res.summaries[("leo-phase+imu", 10)]
    st, co = out["states"], out["consider"]
    assert st["position"]["final_rmse"] < 0.75 * co["position"]["final_rmse"]
    assert st["velocity"]["final_rmse"] < 0.2 * co["velocity"]["final_rmse"]
    lo, hi = st["nees"]["band95"]
    assert lo < st["nees"]["mean"] < hi
    assert st["orbit_states"]["slots_taken"] >= 6 * 10 and st["orbit_states"]["no_slot"] == 0
    assert "orbit_states" not in co


def test_states_scenarios_name_what_they_cannot_do():
    with pytest.raises(UserInputError, match="compensate = 'states' takes the Starlink sigmas"):
        _static("states", starlink_sigma_rac_m=[0.0, 0.0, 0.0])
    raw = copy.deepcopy(load_scenario("passive-phase-base").raw)
    raw["ephemeris_error"]["compensate"] = "states"
    with pytest.raises(UserInputError, match=r"\[base\] enabled = true serves corrected orbits"):
        scenario_from_dict(raw, source="<base with states>")
