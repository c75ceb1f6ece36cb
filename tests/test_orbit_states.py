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


def _reference(recs, x0, P0, params, nav, n_slots, prior_sigma, gate, free_after_s=30.0, q_rw=(0.0, 0.0, 0.0)):
    """The augmented filter in NumPy: the state [dx | offsets of the satellites in slots], a slot
    taken (lowest free, else the one idle longest past free_after_s, reset to the prior) only by
    an applied record, the offsets walking with PSD q_rw (m^2/s)."""
    L = nav.layout
    ndx = int(L.NDX)
    predict = navfuncs.GeneratedFunction(nav.library.lib, "leonav_predict")
    kinds = orbit_states.offset_kinds()
    x, m = np.array(x0, float), 3 * n_slots
    P = np.zeros((ndx + m, ndx + m))
    P[:ndx, :ndx] = P0
    off = np.zeros(m)
    owner = [-1] * n_slots        # satellite per slot
    last = [0.0] * n_slots        # its last applied record
    taken, reused, no_slot = 0, 0, 0
    for r in recs:
        t = float(r["t"])
        if r["kind"] < 0:
            x_n, P_n, F, _ = predict(x, P[:ndx, :ndx], r["u"], float(r["dt"]), params)
            x = x_n[:, 0]
            P[:ndx, ndx:] = F @ P[:ndx, ndx:]
            P[ndx:, :ndx] = P[:ndx, ndx:].T
            P[:ndx, :ndx] = P_n
            for j in range(n_slots):
                if owner[j] >= 0:
                    c = ndx + 3 * j
                    P[c:c + 3, c:c + 3] += np.diag(np.asarray(q_rw) * float(r["dt"]))
            continue
        H = np.zeros(ndx + m)
        Pt, offt, j, new = P, off, None, None
        aux = r["aux"][None]
        if int(r["kind"]) in kinds:
            s = int(r["sat_id"])
            if s in owner:
                j = owner.index(s)
            else:
                free = [k for k in range(n_slots) if owner[k] < 0]
                idle = [k for k in range(n_slots) if owner[k] >= 0 and t - last[k] > free_after_s]
                if not free and not idle:
                    no_slot += 1
                    continue
                j = free[0] if free else min(idle, key=lambda k: last[k])
                new = (s, not free)
                c = ndx + 3 * j
                Pt, offt = P.copy(), off.copy()
                Pt[c:c + 3, :] = 0.0
                Pt[:, c:c + 3] = 0.0
                Pt[c:c + 3, c:c + 3] = np.diag(np.asarray(prior_sigma) ** 2)
                offt[3 * j:3 * j + 3] = 0.0
            d = offt[3 * j:3 * j + 3]
            h, H[:ndx] = nav.h(int(r["kind"]), x, move_aux(aux, d[None], L)[0])
            for a in range(3):
                e = np.eye(3)[a]
                hp = nav.h(int(r["kind"]), x, move_aux(aux, (d + e)[None], L)[0])[0]
                hm = nav.h(int(r["kind"]), x, move_aux(aux, (d - e)[None], L)[0])[0]
                H[ndx + 3 * j + a] = (hp - hm) / 2.0
        else:
            h, H[:ndx] = nav.h(int(r["kind"]), x, r["aux"])
        y = r["z"] - h
        b = Pt @ H
        S = H @ b + r["R"]
        if y * y / S > gate:
            continue
        K = b / S
        x = nav.boxplus(x, K[:ndx] * y)
        P, off = Pt - np.outer(b, b) / S, offt + K[ndx:] * y
        if j is not None:
            last[j] = t
        if new:
            owner[j] = new[0]
            taken += 1
            reused += int(new[1])
    counts = {"slots_taken": taken, "slots_reused": reused, "no_slot": no_slot}
    return x, P, off, {s: k for k, s in enumerate(owner) if s >= 0}, counts


def _agree(ekf, orbit, x_ref, P_ref, off_ref, nav):
    """The C run against the NumPy one, measured against the sigmas (module doc of the test below)."""
    ndx = int(nav.layout.NDX)
    m = 3 * orbit.c.n_slots
    sig_x = np.sqrt(np.diag(P_ref[:ndx, :ndx]))
    used = sig_x > 0
    sig_o = np.sqrt(np.diag(P_ref[ndx:, ndx:]))
    on = sig_o > 0                               # the offsets of slots in use
    assert np.max(np.abs(nav.boxminus(ekf.x, x_ref)[used] / sig_x[used])) < 1e-3
    assert np.max(np.abs(orbit.offset[on] - off_ref[on]) / sig_o[on]) < 1e-3
    np.testing.assert_allclose(np.sqrt(np.diag(ekf.P))[used], sig_x[used], rtol=1e-3)
    cov = orbit.offset_covariance()
    np.testing.assert_allclose(np.sqrt(np.diag(cov))[on], sig_o[on], rtol=1e-3)
    norm = np.outer(sig_o[on], sig_o[on])
    np.testing.assert_allclose(cov[np.ix_(on, on)] / norm, P_ref[ndx:, ndx:][np.ix_(on, on)] / norm, atol=1e-3)
    corr = P_ref[:ndx, ndx:][np.ix_(used, on)] / np.outer(sig_x[used], sig_o[on])
    np.testing.assert_allclose(orbit.P_no.T[np.ix_(used, on)] / np.outer(sig_x[used], sig_o[on]), corr, atol=1e-3)
    assert not np.any(np.tril(orbit.P_oo, -1))   # the C writes one triangle (column-major lower)
    assert m == P_ref.shape[0] - ndx
    return cov


def _noisy(stream, seed=7):
    setup, nav, recs, x_lin = stream
    rng = np.random.default_rng(seed)
    noisy = recs.copy()
    meas = noisy["kind"] >= 0
    noisy["z"][meas] += rng.standard_normal(int(meas.sum())) * np.sqrt(noisy["R"][meas])
    x0 = nav.boxplus(x_lin[0], rng.normal(0, 1, int(nav.layout.NDX)) * np.sqrt(np.diag(setup.P0)))
    return noisy, x0


def test_the_c_filter_is_the_textbook_augmented_filter(stream):
    """A phase update removes most of a 10 m prior's variance at once (S is 1e-5 of H P H^T), so
    the two roundings part by more than 1e-9 in absolute terms; measured against the sigmas they
    agree to < 1e-3 (the C's expanded Joseph form against P - b b^T / S here)."""
    setup, nav, recs, x_lin = stream
    noisy, x0 = _noisy(stream)
    sigma = [240.0, 960.0, 170.0]
    orbit = orbit_states.OrbitStates(nav.layout.NDX, len(nav.library.meas_ids), 8, sigma)
    ekf = lfilter.EKF(x0, setup.P0, setup.params, gate=10.83, library=nav.library)
    res = ekf.run(noisy, orbit=orbit)
    x_ref, P_ref, off_ref, slots, counts = _reference(noisy, x0, setup.P0, setup.params, nav, 8, sigma, 10.83)
    assert orbit.counts == counts == {"slots_taken": 6, "slots_reused": 0, "no_slot": 0}
    assert res.n_applied > 0.95 * np.sum(noisy["kind"] >= 0)
    assert {s: j for j, s in enumerate(orbit.slot_sat.tolist()) if s >= 0} == slots
    cov = _agree(ekf, orbit, x_ref, P_ref, off_ref, nav)
    # the offsets are information: they do not leave the prior's sigmas unchanged
    on = np.flatnonzero(np.diag(cov) > 0)
    assert np.all(np.sqrt(np.diag(cov))[on] < np.tile(sigma, len(slots)))


def test_slots_reused_and_walking_offsets_are_the_textbook_filter_too(stream):
    """The same against the NumPy filter when slots run out and are reused and the offsets walk:
    after 3 s every satellite is "new" (ids + 1000); 2 take the free slots, the rest find none
    (counted) until the old satellites have been idle for free_after_s = 0.5 s and give theirs up."""
    setup, nav, recs, x_lin = stream
    noisy, x0 = _noisy(stream, seed=8)
    late = (noisy["t"] > 3.0) & np.isin(noisy["kind"], sorted(orbit_states.offset_kinds()))
    noisy["sat_id"][late] += 1000
    sigma, q = [100.0, 400.0, 100.0], [1.0, 20.0, 1.0]
    orbit = orbit_states.OrbitStates(nav.layout.NDX, len(nav.library.meas_ids), 8, sigma, q, free_after_s=0.5)
    ekf = lfilter.EKF(x0, setup.P0, setup.params, gate=10.83, library=nav.library)
    ekf.run(noisy, orbit=orbit)
    x_ref, P_ref, off_ref, slots, counts = _reference(noisy, x0, setup.P0, setup.params, nav, 8, sigma, 10.83,
                                                      free_after_s=0.5, q_rw=q)
    assert orbit.counts == counts
    assert counts["slots_taken"] == 12 and counts["slots_reused"] == 4 and counts["no_slot"] > 0
    assert {s: j for j, s in enumerate(orbit.slot_sat.tolist()) if s >= 0} == slots
    _agree(ekf, orbit, x_ref, P_ref, off_ref, nav)


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


def test_a_record_not_applied_changes_nothing(stream):
    """A satellite whose every record is gated never takes a slot (status GATED, the slot left
    free); a record with a non-finite aux entry fails as in leonav_run, even one h does not read;
    and a caller's slot table with a free slot between taken ones is refused."""
    setup, nav, recs, x_lin = stream
    L = nav.layout
    kinds = sorted(orbit_states.offset_kinds())
    sats = np.unique(recs["sat_id"][np.isin(recs["kind"], kinds)])
    bad = recs.copy()
    mine = np.isin(bad["kind"], kinds) & (bad["sat_id"] == sats[0])
    bad["z"][mine] += 1e6
    orbit = orbit_states.OrbitStates(L.NDX, len(nav.library.meas_ids), 8, [240.0, 960.0, 170.0])
    res = lfilter.EKF(x_lin[0], setup.P0, setup.params, gate=10.83, library=nav.library).run(bad, orbit=orbit)
    assert np.all(res.status[mine] == lfilter.STATUS_GATED)
    assert int(sats[0]) not in orbit.slot_sat.tolist() and orbit.counts["slots_taken"] == sats.size - 1
    nan = recs.copy()
    row = int(np.flatnonzero(np.isin(nan["kind"], kinds))[3])
    nan["aux"][row, L.AUX_KLOBUCHAR] = np.nan      # an entry the Starlink models do not read
    plain = lfilter.EKF(x_lin[0], setup.P0, setup.params, library=nav.library).run(nan)
    orbit = orbit_states.OrbitStates(L.NDX, len(nav.library.meas_ids), 8, [240.0, 960.0, 170.0])
    states = lfilter.EKF(x_lin[0], setup.P0, setup.params, library=nav.library).run(nan, orbit=orbit)
    assert plain.status[row] == states.status[row] == lfilter.STATUS_FAILED
    gap = orbit_states.OrbitStates(L.NDX, len(nav.library.meas_ids), 4, [1.0, 1.0, 1.0])
    gap.slot_sat[:] = [5, -1, 7, -1]
    with pytest.raises(RuntimeError, match="LEONAV_ERR_ARG"):
        lfilter.EKF(x_lin[0], setup.P0, setup.params, library=nav.library).run(recs[:5], orbit=gap)


def test_under_states_the_kinds_without_offsets_keep_the_consider_term():
    """`compensate = "states"` estimates the offsets of the undifferenced Starlink observables; the
    differenced range (it reads a reference satellite too) and GPS, when its orbits are perturbed,
    keep the consider term, so a mode of theirs is not left with an uncompensated orbit error."""
    from leonav_runtime.simulation import realism

    scn = _static("states", apply_to=["starlink", "gps"])
    terms = realism.orbit_consider(scn).sigma_rac_m
    assert set(terms) == {"ofdm_range_diff", "pseudorange"}
    assert not set(terms) & orbit_states.offset_observables()
    assert orbit_states.offset_observables() == {"carrier_phase", "doppler_rate", "doppler"}
    assert realism.orbit_consider(_static("none")) is None
