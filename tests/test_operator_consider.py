"""The operator ephemeris's covariance reaches the filter: the consider term of each record's
R becomes J P_operator J^T (inputs/consider.py with orbits/operator_consider.py)."""
from __future__ import annotations

import copy
import datetime as dt

import numpy as np
import pytest

from leonav_runtime.gen import state_layout as L
from leonav_runtime.inputs import SATELLITE_TABLES, consider
from leonav_runtime.inputs.imu import averaged_specific_force
from leonav_runtime.inputs.measurements import satellite_records
from leonav_runtime.inputs.tables import ImuTable
from leonav_runtime.orbits.eme2000 import ecef_to_eme2000
from leonav_runtime.orbits.operator_consider import OperatorCovariance, names_by_id
from leonav_runtime.orbits.operator_ephemeris import (
    OperatorEphemeris,
    OperatorEphemerisSet,
)
from leonav_runtime.orbits.propagate import propagate_ecef
from leonav_runtime.scenarios.load import load_scenario, scenario_from_dict
from leonav_runtime.simulation import simulate
from leonav_runtime.simulation.visibility import scenario_elements
from leonav_runtime.sweep import montecarlo as mc


@pytest.fixture(scope="module")
def run():
    """The paper run's Doppler-rate records (10 satellites, 3 s) and operator ephemerides of
    the same satellites (their SGP4 orbits written as EME2000 states every 60 s)."""
    raw = copy.deepcopy(load_scenario("paper").raw)
    raw["time"]["duration_s"] = 3.0
    raw["starlink"]["counts"] = [10]
    raw["monte_carlo"]["modes"] = ["leo-alpha+imu"]
    scn = scenario_from_dict(raw, source="<operator consider test>")
    setup, nav = mc.setup_for(scn)
    s = setup.series["doppler_rate"]
    rows = simulate.selected_rows(setup, "doppler_rate", 10)
    es = scenario_elements(scn)["starlink"]
    ids = np.unique(s.sat_id[rows])
    pick = [int(np.flatnonzero(es.norad_ids == i)[0]) for i in ids]
    t_nodes = np.array([-60.0, 0.0, 60.0, 120.0])
    st = propagate_ecef(es.select(pick), scn.epoch_utc, t_nodes, acceleration=False, warn_stale=False)
    ids_to_names = names_by_id(ids, [f"SAT-{i}" for i in ids])
    start = scn.epoch_utc - dt.timedelta(seconds=60)
    ephs = {}
    for j, sid in enumerate(ids):
        r, v = ecef_to_eme2000(st.r_ecef_m[j], st.v_ecef_mps[j], scn.epoch_utc, t_nodes)
        ephs[ids_to_names[int(sid)]] = OperatorEphemeris("<fixture>", ids_to_names[int(sid)], None, start,
                                                         start + dt.timedelta(seconds=180), 60.0, "fixture", "UVW",
                                                         np.arange(4, dtype=np.int64) * 60000, r, v, np.zeros((4, 6, 6)))
    return scn, setup, nav, s, rows, OperatorEphemerisSet(ephs), ids_to_names


def _table(s, rows, kind="doppler_rate", ref=None):
    return SATELLITE_TABLES[kind](s.t_s[rows], s.sat_id[rows], s.z_true[rows], 0.05, s.sat_ecef[rows], ref)


def _with_cov(ephs: OperatorEphemerisSet, cov_uvw: np.ndarray) -> OperatorEphemerisSet:
    out = {}
    for name, e in ephs.ephemerides.items():
        e = copy.copy(e)
        e.cov_uvw = np.broadcast_to(cov_uvw, (len(e), 6, 6)).copy()
        out[name] = e
    return OperatorEphemerisSet(out)


def test_radial_operator_covariance_gives_the_models_radial_consider_term(run):
    """Radial direction is the same in every frame: an operator covariance with only radial
    variance must give the element-age model's radial-only P position block and consider
    term; its ECEF velocity block is the Earth-rate term -w x dr (the inertial velocity is
    exact), which the model leaves out."""
    from leonav_runtime.orbits.teme import OMEGA_EARTH_RADPS
    scn, setup, nav, s, rows, ephs, ids = run
    cov = np.zeros((6, 6))
    cov[0, 0] = 30.0 ** 2
    provider = OperatorCovariance(_with_cov(ephs, cov), scn.epoch_utc, ids)
    table, aux, x0 = _table(s, rows), s.aux[rows], setup.x_true[0]
    p = provider.covariance_ecef(table.sat_id, table.t, table.sat_ecef)
    u = table.sat_ecef[:, 0:3] / np.linalg.norm(table.sat_ecef[:, 0:3], axis=1, keepdims=True)
    np.testing.assert_allclose(p[:, 0:3, 0:3], 900.0 * np.einsum("ni,nj->nij", u, u), atol=1e-3)   # m^2
    w = np.array([[0.0, -OMEGA_EARTH_RADPS, 0.0], [OMEGA_EARTH_RADPS, 0.0, 0.0], [0.0, 0.0, 0.0]])
    np.testing.assert_allclose(p[:, 3:6, 3:6], w @ p[:, 0:3, 0:3] @ w.T, atol=1e-9)
    var = consider.OrbitConsider({}, covariance={"doppler_rate": provider}).variance(table, aux, x0, setup.params, nav)
    J = nav.orbit_jacobian_many("doppler_rate", x0, aux, setup.params)
    assert provider.uncovered_records == 0
    assert var.min() > 0 and var == pytest.approx(consider.covariance_variance(J, p, None), rel=1e-12)
    j_pos = J.copy()
    j_pos[:, 3:12] = 0.0                                   # the position part alone
    assert consider.covariance_variance(j_pos, p, None) == pytest.approx(
        consider.consider_variance(j_pos, table.sat_ecef, None, np.array([30.0, 0.0, 0.0])), rel=1e-5)


def test_r_follows_the_files_covariance(run):
    scn, setup, nav, s, rows, ephs, ids = run
    rng = np.random.default_rng(3)
    a = rng.standard_normal((6, 6)) * np.array([1.0, 8.0, 1.5, 2e-3, 1e-3, 2e-3])[:, None]
    cov = a @ a.T
    table, x0 = _table(s, rows), setup.x_true[0]
    dvel = setup.u_true[:, L.U_DVEL_B_SLICE]
    imu = ImuTable.from_increments(setup.t_imu[1:], np.diff(setup.t_imu), setup.u_true[:, L.U_DTHETA_B_SLICE], dvel)
    f_avg, span = averaged_specific_force(dvel, np.diff(setup.t_imu))

    def r_of(cov_uvw):
        prov = OperatorCovariance(_with_cov(ephs, cov_uvw), scn.epoch_utc, ids)
        oc = consider.OrbitConsider({}, covariance={"doppler_rate": prov})
        return satellite_records(table, imu, f_avg, span, setup.params, nav, oc, x0)["R"]
    base = satellite_records(table, imu, f_avg, span, setup.params, nav, None, x0)["R"]
    extra1, extra4 = r_of(cov) - base, r_of(4.0 * cov) - base
    assert extra1.min() > 0
    assert extra4 == pytest.approx(4.0 * extra1, rel=1e-9)                 # R moves with the file
    inflated = cov.copy()
    inflated[1, 1] *= 100.0                                                # in-track variance x 100
    assert np.all(r_of(inflated) - base > 2.0 * extra1)


def test_uncovered_records_fall_back_to_the_model_and_are_counted(run):
    scn, setup, nav, s, rows, ephs, ids = run
    cov = np.zeros((6, 6))
    cov[0, 0] = 30.0 ** 2
    dropped = dict(ids)
    gone = min(dropped)
    del dropped[gone]                       # one satellite without a file
    provider = OperatorCovariance(_with_cov(ephs, cov), scn.epoch_utc, dropped)
    table, aux, x0 = _table(s, rows), s.aux[rows], setup.x_true[0]
    sig = np.array([240.0, 960.0, 170.0])
    with pytest.warns(UserWarning, match="no operator covariance"):
        var = consider.OrbitConsider({"doppler_rate": sig}, covariance={"doppler_rate": provider}).variance(
            table, aux, x0, setup.params, nav)
    J = nav.orbit_jacobian_many("doppler_rate", x0, aux, setup.params)
    mine = table.sat_id == gone
    assert provider.uncovered_records == int(mine.sum()) > 0
    assert var[mine] == pytest.approx(consider.consider_variance(J[mine], s.sat_ecef[rows][mine], None, sig))
    p = provider.covariance_ecef(table.sat_id[~mine], table.t[~mine], table.sat_ecef[~mine])
    assert var[~mine] == pytest.approx(consider.covariance_variance(J[~mine], p, None), rel=1e-12)


def test_a_differenced_observables_reference_is_found_by_its_state(run):
    scn, _setup, _nav, s, rows, ephs, ids = run
    cov = np.zeros((6, 6))
    cov[0, 0] = 30.0 ** 2
    provider = OperatorCovariance(_with_cov(ephs, cov), scn.epoch_utc, ids)
    ref = np.roll(s.sat_ecef[rows], 3, axis=0)          # another satellite of the same epoch set
    p_by_state = provider.covariance_ecef(None, s.t_s[rows], ref)
    ref_ids = np.roll(s.sat_id[rows], 3)
    same_time = np.roll(s.t_s[rows], 3) == s.t_s[rows]
    p_by_id = provider.covariance_ecef(ref_ids, s.t_s[rows], ref)
    assert same_time.sum() > 5
    np.testing.assert_allclose(p_by_state[same_time], p_by_id[same_time], rtol=1e-9, atol=1e-12)
    far = ref.copy()
    far[:, 0:3] += 200e3                                # nothing within 50 km: not covered
    with pytest.warns(UserWarning, match="30 of 30 records have no operator covariance"):
        assert np.isnan(provider.covariance_ecef(None, s.t_s[rows], far)).all()


def _scenario(**eph):
    raw = copy.deepcopy(load_scenario("paper").raw)
    raw["time"]["duration_s"] = 3.0
    raw["starlink"]["counts"] = [10]
    raw["monte_carlo"]["modes"] = ["leo-alpha+imu"]
    raw["ephemeris_error"] = dict(eph)
    return scenario_from_dict(raw, source="<operator consider scenario>")


def _write_folder(run, folder, cov_uvw):
    """The run's satellites as operator files named like their element sets."""
    from leonav_runtime.orbits.operator_ephemeris import write_file
    scn, _, _, _, _, ephs, ids = run
    es = scenario_elements(scn)["starlink"]
    for k, (sid, name) in enumerate(ids.items()):
        e = copy.copy(ephs.ephemerides[name])
        e.name = str(es.names[int(np.flatnonzero(es.norad_ids == sid)[0])])
        e.cov_uvw = np.broadcast_to(cov_uvw, (len(e), 6, 6)).copy()
        write_file(e, folder, serial=k)


def test_a_scenarios_operator_folder_feeds_the_consider_term(run, tmp_path):
    scn0, setup, nav, *_ = run
    rng = np.random.default_rng(5)
    a = rng.standard_normal((6, 6)) * np.array([2.0, 9.0, 1.5, 2e-3, 1e-3, 2e-3])[:, None]
    cov = a @ a.T
    _write_folder(run, tmp_path / "x1", cov)
    _write_folder(run, tmp_path / "x4", 4.0 * cov)

    def alpha_r(**eph):
        scn = _scenario(**eph)
        s, n = mc.setup_for(scn)
        trial = simulate.trial_records(s, "leo-alpha+imu", 10, mc.trial_rng(scn.seed, 0), n)
        alpha = trial.records["kind"] == n.kind_id("doppler_rate")
        return trial.records["R"][alpha], trial.records[alpha], trial.x0
    base, recs, x0 = alpha_r()
    model, _, _ = alpha_r(compensate="consider")
    op1, _, _ = alpha_r(compensate="consider", operator_folder=str(tmp_path / "x1"))
    op4, _, _ = alpha_r(compensate="consider", operator_folder=str(tmp_path / "x4"))
    J = nav.orbit_jacobian_many("doppler_rate", x0, recs["aux"], setup.params)
    from leonav_runtime.orbits.operator_consider import folder_covariance
    prov = folder_covariance(tmp_path / "x1", scenario_elements(scn0)["starlink"], scn0.epoch_utc)
    p = prov.covariance_ecef(recs["sat_id"], recs["t"], np.zeros((recs.size, 9)))
    assert prov.uncovered_records == 0
    assert op1 - base == pytest.approx(consider.covariance_variance(J, p, None), rel=1e-9)
    assert op4 - base == pytest.approx(4.0 * (op1 - base), rel=1e-9)        # R follows the files
    assert np.abs((op1 - base) / (model - base) - 1.0).min() > 0.5           # not the element-age model


def test_operator_folder_bad_input_is_one_line(tmp_path):
    from leonav_runtime.common.errors import UserInputError
    with pytest.raises(UserInputError, match=r"operator_folder = .* is used only by compensate = 'consider'"):
        _scenario(operator_folder=str(tmp_path))
    with pytest.raises(UserInputError, match=r"operator_folder = .*missing.* is not a folder"):
        _scenario(compensate="consider", operator_folder=str(tmp_path / "missing"))
