"""Propagation: TEME against Vallado's tcppver.out, ECEF/acceleration against skyfield."""
from __future__ import annotations

import datetime as dt
import warnings

import numpy as np
import pytest

from leonav_runtime.orbits import (
    StaleElementsWarning,
    load_elements,
    propagate_ecef,
    propagate_teme,
)
from leonav_runtime.orbits.teme import gmst82_rad, teme_to_ecef
from tests.conftest import shared_file
from tests.eop_reference import skyfield_timescale_same_eop

UTC = dt.timezone.utc
skyfield_api = pytest.importorskip("skyfield.api", reason="skyfield is the independent ECEF reference")
from skyfield.framelib import itrs  # noqa: E402
from skyfield.sgp4lib import TEME_to_ITRF  # noqa: E402


def _quiet_load(path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_elements(path, **kw)


def _tcppver_blocks(path) -> list[tuple[int, np.ndarray]]:
    """[(catalog number, rows of t_min, r_km(3), v_kmps(3))] in file order."""
    blocks: list[tuple[int, list]] = []
    for line in path.read_text().splitlines():
        if line.rstrip().endswith("xx"):
            blocks.append((int(line.split()[0]), []))
        elif line.strip():
            blocks[-1][1].append([float(x) for x in line.split()[:7]])
    return [(n, np.array(rows)) for n, rows in blocks]


def test_teme_matches_vallado_tcppver():
    elements = _quiet_load(shared_file("sgp4/SGP4-VER.TLE"), strict_checksum=False)
    blocks = _tcppver_blocks(shared_file("sgp4/tcppver.out"))
    assert len(blocks) == len(elements) == 33
    worst_r_m = worst_v_mps = 0.0
    compared = 0
    for i, (number, rows) in enumerate(blocks):
        assert elements.norad_ids[i] == number
        one = elements.select([i])
        err, r_km, v_kmps = propagate_teme(one, one.epochs_utc[0], rows[:, 0] * 60.0)
        good = err[0] == 0
        if number == 33334:  # Vallado's "error code" case: tcppver prints a stale line at t=0
            assert not good.any()
            continue
        assert good.all(), (number, err[0])
        worst_r_m = max(worst_r_m, np.max(np.linalg.norm(r_km[0] - rows[:, 1:4], axis=1)) * 1e3)
        worst_v_mps = max(worst_v_mps, np.max(np.linalg.norm(v_kmps[0] - rows[:, 4:7], axis=1)) * 1e3)
        compared += len(rows)
    assert compared > 600
    # tcppver prints 1e-8 km; the element epoch passes through a datetime (1 us) and the
    # SL-12 case is propagated to t = 1.8e6 min.
    print(f"tcppver: {compared} states, max |dr| {worst_r_m:.2e} m, |dv| {worst_v_mps:.2e} m/s")
    assert worst_r_m < 1e-3, worst_r_m
    assert worst_v_mps < 1e-5, worst_v_mps


def test_error_cases_are_reported_by_name_and_the_batch_goes_on():
    elements = _quiet_load(shared_file("sgp4/SGP4-VER.TLE"), strict_checksum=False)
    index = {n: i for i, n in enumerate(elements.norad_ids.tolist())}
    pick = elements.select([index[33333], index[5], index[33334], index[33335]])
    t_s = np.arange(0.0, 150.0 * 60.0 + 1.0, 300.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StaleElementsWarning)
        states = propagate_ecef(pick, pick.epochs_utc[0], t_s)
    assert states.ok.tolist() == [False, True, False, True]
    names = [f[0] for f in states.failures]
    assert names == ["33333", "33334"]
    assert "SGP4 error 4: semi-latus rectum" in states.failures[0][2]
    assert "first at t = 1500 s" in states.failures[0][2]  # tcppver stops after 20 min
    assert np.isfinite(states.r_ecef_m[0, :5]).all() and np.isnan(states.r_ecef_m[0, 5:]).all()
    assert np.isnan(states.v_ecef_mps[2]).all() and np.isnan(states.a_ecef_mps2[2]).all()
    assert np.isfinite(states.r_ecef_m[[1, 3]]).all()


def _sample(elements, count, seed):
    rng = np.random.default_rng(seed)
    return elements.select(np.sort(rng.choice(len(elements), size=count, replace=False)))


@pytest.mark.parametrize("name, epoch", [
    ("tle/starlink_2026-02-23.txt", dt.datetime(2026, 2, 23, 12, 0, 0, tzinfo=UTC)),
    ("tle/gps-ops_2026-03-09.txt", dt.datetime(2026, 3, 9, 6, 30, 0, tzinfo=UTC)),
])
def test_ecef_state_and_acceleration_match_skyfield(name, epoch):
    elements = _sample(_quiet_load(shared_file(name)), 20, seed=7)
    ts = skyfield_timescale_same_eop()  # UT1-UTC and polar motion from leonav's IERS table
    t_s = np.array([0.0, 1234.5, 3 * 3600.0 + 17.0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StaleElementsWarning)
        states = propagate_ecef(elements, epoch, t_s)  # default: the IERS table
    assert states.ok.all() and states.r_ecef_m.shape == (20, 3, 3)
    h = 2.0  # s, second-difference step for the acceleration reference
    dr = dv = da = 0.0
    for i, satrec in enumerate(elements.satrecs):
        sat = skyfield_api.EarthSatellite.from_satrec(satrec, ts)
        for j, t in enumerate(t_s):
            when = ts.utc(epoch.year, epoch.month, epoch.day, epoch.hour, epoch.minute,
                          epoch.second + t + np.array([-h, 0.0, h]))
            pos, vel = sat.at(when).frame_xyz_and_velocity(itrs)
            r = pos.m
            dr = max(dr, np.linalg.norm(states.r_ecef_m[i, j] - r[:, 1]))
            dv = max(dv, np.linalg.norm(states.v_ecef_mps[i, j] - vel.m_per_s[:, 1]))
            a_ref = (r[:, 2] - 2.0 * r[:, 1] + r[:, 0]) / h**2
            da = max(da, np.linalg.norm(states.a_ecef_mps2[i, j] - a_ref))
    print(f"{name}: max |dr| {dr:.2e} m, |dv| {dv:.2e} m/s, |da| {da:.2e} m/s^2 vs skyfield")
    assert dr < 0.05, dr  # m (same EOP on both sides: a few mm)
    # skyfield's ITRS velocity takes the Earth-rotation term about the ITRS z axis, not the
    # rotation pole (its framelib says so): off by |w x r| * |polar motion| ~ 1.9 km/s * 2e-6
    # = 4 mm/s at GPS radius; ours rotates v_pef by PM as Vallado's teme2ecef.
    assert dv < 6e-3, dv  # m/s
    assert da < 1e-3, da  # m/s^2
    # the reference is not trivially small (GPS: ~0.4 m/s^2 in ECEF, LEO: ~8 m/s^2)
    assert np.linalg.norm(states.a_ecef_mps2, axis=-1).min() > 0.3


def test_ut1_and_polar_motion_against_skyfield_teme_to_itrf():
    elements = _quiet_load(shared_file("tle/gps-ops_2026-03-09.txt")).select([0, 5, 9])
    epoch = dt.datetime(2026, 3, 9, tzinfo=UTC)
    t_s = np.array([0.0, 5000.0])
    ut1_utc, xp_arcsec, yp_arcsec = -0.35, 0.12, 0.38
    arcsec = np.pi / 180.0 / 3600.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StaleElementsWarning)
        states = propagate_ecef(elements, epoch, t_s, ut1_utc_s=ut1_utc, xp_rad=xp_arcsec * arcsec,
                                yp_rad=yp_arcsec * arcsec, acceleration=False)
    assert states.a_ecef_mps2 is None
    _, r_km, v_kmps = propagate_teme(elements, epoch, t_s)
    jd_ut1 = np.full(t_s.shape, 2461108.5)  # 2026-03-09 0h; the day fraction passed apart
    fraction_ut1 = (t_s + ut1_utc) / 86400.0
    for i in range(len(elements)):
        # skyfield: polar motion in rad, velocity per day; its Earth rate is dGMST82/dt,
        # Vallado's (ours) is 7.292115147e-5 rad/s: 7e-12 rad/s apart, 0.2 mm/s at GPS radius
        r_ref, v_ref = TEME_to_ITRF(jd_ut1, r_km[i].T, v_kmps[i].T * 86400.0, xp_arcsec * arcsec,
                                    yp_arcsec * arcsec, fraction_ut1)
        np.testing.assert_allclose(states.r_ecef_m[i], r_ref.T * 1e3, rtol=0, atol=2e-3)
        np.testing.assert_allclose(states.v_ecef_mps[i], v_ref.T * 1e3 / 86400.0, rtol=0, atol=5e-4)
    # and UT1-UTC really matters: 0.35 s of Earth rotation moves a GPS satellite ~0.6 km
    plain = propagate_ecef(elements, epoch, t_s, ut1_utc_s=0.0, xp_rad=0.0, yp_rad=0.0, acceleration=False)
    assert np.linalg.norm(plain.r_ecef_m - states.r_ecef_m, axis=-1).min() > 100.0


def test_gmst_and_frame_rotation_basics():
    # IAU-82 GMST at J2000.0 (2000-01-01 12:00 UT1) is 280.46061837 deg
    assert np.degrees(gmst82_rad(2451545.0, 0.0)) == pytest.approx(280.46061837, abs=1e-8)
    # TEME -> ECEF keeps |r| and |v_inertial|^2 - ... : |r| invariant
    r = np.array([[[7000.0, 100.0, 300.0]]])
    v = np.array([[[0.1, 7.5, 0.2]]])
    re, ve = teme_to_ecef(r, v, np.array([1.0]))
    assert np.linalg.norm(re) == pytest.approx(np.linalg.norm(r))
    assert re[0, 0, 2] == r[0, 0, 2] and ve[0, 0, 2] == v[0, 0, 2]


def test_stale_elements_warning_fires_past_the_threshold():
    elements = _quiet_load(shared_file("tle/gps-ops_2026-03-09.txt"), stale_after_days=3.0)
    newest = max(elements.epochs_utc)
    oldest = min(elements.epochs_utc)
    with warnings.catch_warnings():
        warnings.simplefilter("error", StaleElementsWarning)
        # every element set within 3 days of the scenario (oldest is 6.5 d before newest)
        propagate_ecef(elements.select(elements.ages_s(newest) < 2.5 * 86400), newest, [0.0, 600.0])
    with pytest.warns(StaleElementsWarning, match=r"32 of 32 gps element sets are more than 3 days.*their satellites are kilometres"):
        propagate_ecef(elements, newest + dt.timedelta(days=3.5), [0.0])
    scenario = oldest + dt.timedelta(days=3.3)
    expected = sum(abs((scenario - e).total_seconds()) > 3 * 86400 for e in elements.epochs_utc)
    assert 0 < expected < 32
    with pytest.warns(StaleElementsWarning, match=rf"{expected} of 32 .*more than 3 days") as record:
        propagate_ecef(elements, scenario, [0.0])
    assert "worst" in str(record[0].message)
    with warnings.catch_warnings():
        warnings.simplefilter("error", StaleElementsWarning)
        propagate_ecef(elements, scenario, [0.0], warn_stale=False)  # caller warns once itself
    # a long scenario makes elements stale by its end
    fresh = elements.select([int(np.argmax(elements.epochs_utc))])
    with pytest.warns(StaleElementsWarning):
        propagate_ecef(fresh, newest, [0.0, 4 * 86400.0])


def test_stale_warning_of_a_scenario_counts_the_users_whole_file_and_blames_its_constellation():
    """A scenario on the user's own GPS file ten days after its sets: the warning counts the 32
    sets of the file (not the dozen the simulation keeps as visible candidates) and names GPS,
    without blaming the LEO Doppler error."""
    from leonav_runtime.scenarios.load import load_scenario
    from leonav_runtime.scenarios.overrides import apply_overrides
    from leonav_runtime.simulation.simulate import prepare

    gps = shared_file("tle/gps-ops_2026-03-09.txt")
    newest = max(_quiet_load(gps).epochs_utc)
    epoch = (newest + dt.timedelta(days=10)).strftime("%Y-%m-%dT%H:%M:%SZ")
    scn, _ = apply_overrides(load_scenario("paper"), modes=["gps+imu"], counts=[5], trials=1,
                             sets=["elements.source=files", f"elements.files=[\"{gps}\"]",
                                   f"time.epoch={epoch}", "time.duration_s=20"])
    with pytest.warns(StaleElementsWarning) as record:
        prepare(scn)
    gps_warnings = [str(w.message) for w in record if "gps element sets" in str(w.message)]
    assert len(gps_warnings) == 1, [str(w.message) for w in record]
    assert gps_warnings[0].startswith("32 of 32 gps element sets")
    assert "LEO Doppler" not in gps_warnings[0]
