"""The PCRB with each satellite's orbit offset as a state (sweep/orbit_bound.py): without offset
states it is the generated filter's own PCRB (information form, in C); the offsets' Jacobian is
the generated orbit Jacobian's (the consider term's, symbolic) for the same move of the orbit;
estimating offsets costs position information, the more the wider their prior; and the command
writes its files."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from tests.conftest import orbit_phase_stream
from leonav_runtime.core import filter as lfilter
from leonav_runtime.inputs.consider import rac_axes
from leonav_runtime.sweep import orbit_bound as ob

MODE = "leo-phase+alpha+imu"


@pytest.fixture(scope="module")
def stream():
    return orbit_phase_stream(16.0, 8, MODE)


def test_without_offset_states_it_is_the_filters_own_pcrb(stream):
    setup, nav, recs, x_lin = stream
    mine = ob.bound(recs, x_lin, setup.P0, setup.params, nav, None)
    ref = lfilter.pcrb(recs, x_lin, setup.P0, setup.params, library=nav.library)
    t = recs["t"]
    ends = np.r_[t[1:] != t[:-1], True]           # C updates record by record: compare whole epochs
    pos = np.sqrt(np.trace(ref.B_nav[:, 0:3, 0:3], axis1=1, axis2=2))
    vel = np.sqrt(np.trace(ref.B_nav[:, 3:6, 3:6], axis1=1, axis2=2))
    np.testing.assert_allclose(mine.position_m[ends], pos[ends], rtol=1e-6)
    np.testing.assert_allclose(mine.velocity_mps[ends], vel[ends], rtol=1e-6)
    assert mine.sat_id.size == 0 and mine.measurements == int(np.sum(recs["kind"] >= 0))


def test_offset_jacobian_is_the_generated_orbit_jacobian_of_the_same_move(stream):
    """An offset d along a satellite's own radial or cross axis moves r_S by d times the axis (the
    truth's error model: `orbit_truth.perturb_states`, the velocity kept); a time difference's
    start moves along its own axis, which has turned with the orbit: through the generated
    orbit Jacobian's fold (start moved by dr - T dv) that is dv = d times the axis's rate (10 %
    of the radial effect on a 0.1 s phase difference). The along-track offset is a time shift
    tau = d / (v . a_hat): dr = v tau, dv = a tau. Contracted with the generated orbit Jacobian
    (d h / d [r_S, v_S], symbolic) that is the derivative the differences over the moved aux
    give."""
    setup, nav, recs, x_lin = stream
    L = nav.layout
    for kind in ob.offset_kinds() & set(np.unique(recs["kind"]).tolist()):
        idx = np.flatnonzero(recs["kind"] == kind)[::7]
        aux = recs["aux"][idx]
        J = ob.offset_jacobian(nav, kind, x_lin[idx], aux, setup.params)
        G = nav.orbit_jacobian_many(kind, x_lin[idx], aux, setup.params)
        sat9 = aux[:, L.AUX_R_S_ECEF_SLICE.start:L.AUX_R_S_ECEF_SLICE.start + 9]
        axes = rac_axes(sat9)
        r, v, a = sat9[:, 0:3], sat9[:, 3:6], sat9[:, 6:9]

        def along(eps):     # the state eps s later on its local orbit
            return np.hstack([r + v * eps + 0.5 * a * eps**2, v + a * eps, a])
        rate = (rac_axes(along(0.01)) - rac_axes(along(-0.01))) / 0.02          # (n, 3, 3) 1/s
        rate *= (aux[:, L.AUX_DT_PHASE] > 0)[:, None, None]     # a single instant: the velocity kept
        tau = 1.0 / np.einsum("ni,ni->n", v, axes[:, 1])

        def through(dr, dv):
            return np.einsum("ni,ni->n", G[:, 0:3], dr) + np.einsum("ni,ni->n", G[:, 3:6], dv)
        want = np.stack([through(axes[:, 0], rate[:, 0]), through(v * tau[:, None], a * tau[:, None]),
                         through(axes[:, 2], rate[:, 2])], axis=1)
        scale = np.abs(want).max()
        assert scale > 0, kind
        np.testing.assert_allclose(J, want, atol=1e-4 * scale, err_msg=str(kind))


def test_estimated_offsets_cost_information_and_a_tight_prior_costs_none(stream):
    setup, nav, recs, x_lin = stream
    true = ob.bound(recs, x_lin, setup.P0, setup.params, nav, None)
    tight = ob.bound(recs, x_lin, setup.P0, setup.params, nav, np.full(3, 1e-4))
    loose = ob.bound(recs, x_lin, setup.P0, setup.params, nav, np.array([10.0, 100.0, 10.0]))
    looser = ob.bound(recs, x_lin, setup.P0, setup.params, nav, np.array([100.0, 1000.0, 100.0]))
    np.testing.assert_allclose(tight.position_m, true.position_m, rtol=1e-3)
    assert np.all(loose.position_m >= true.position_m * (1 - 1e-9))
    assert np.all(looser.position_m >= loose.position_m * (1 - 1e-9))
    assert loose.position_m[-1] > 2.0 * true.position_m[-1]          # the orbits cost much of the phase
    assert np.unique(recs["sat_id"][recs["kind"] >= 0]).size == loose.sat_id.size
    # what the satellites' offsets are known to at the end: better than their prior, not better than 0
    assert np.all(loose.orbit_sigma_m > 0) and np.all(loose.orbit_sigma_m <= np.array([10.0, 100.0, 10.0]) + 1e-9)


def test_the_command_writes_the_bound_and_names_a_bad_prior(tmp_path, capsys):
    from leonav_runtime.cli import main

    args = ["orbit-bound", "passive-phase-static", "--count", "6", "--set", "time.duration_s=6",
            "--sigma-rac", "1.4,4.7,2.2", "--out", str(tmp_path)]
    assert main(args) == 0
    doc = json.loads((tmp_path / "orbit-bound.json").read_text())
    cases = {c["case"]: c for c in doc["cases"]}
    true, elements, operator = (cases[k]["final_position_m"] for k in
                                ("true orbits", "offsets estimated, element sets 6 h old",
                                 "offsets estimated, prior 1.4/4.7/2.2 m"))
    assert true < operator < elements
    with open(tmp_path / "orbit-bound.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert len(rows) == 1 + 6 and rows[0][0] == "t_s" and len(rows[0]) == 4
    assert all(len(r) == 4 for r in rows)
    assert (tmp_path / "orbit-bound.png").stat().st_size > 1000
    capsys.readouterr()
    assert main(["orbit-bound", "--sigma-rac", "1,2", "--out", str(tmp_path / "bad")]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--sigma-rac '1,2'" in err[0], err
