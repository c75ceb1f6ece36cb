"""Operator (Starlink) ephemeris files: exact round trip, interpolation accuracy against
reference orbits, the UVW covariance rotation, the EME2000 frame against skyfield, and
hostile files refused in one line naming the line."""
from __future__ import annotations

import datetime as dt
import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.orbits.eme2000 import (
    ecef_to_eme2000,
    eme2000_to_ecef,
    eme2000_to_teme_matrix,
)
from leonav_runtime.orbits.operator_ephemeris import (
    OperatorEphemeris,
    OperatorEphemerisSet,
    RejectedEphemerisWarning,
    load_folder,
    parse_text,
    write_file,
    write_text,
)
from leonav_runtime.orbits.operator_states import (
    OperatorCoverageWarning,
    ephemerides_from_elements,
    interpolate_eme2000,
    operator_states_ecef,
    uvw_axes,
    uvw_to_frame,
)
from leonav_runtime.orbits.propagate import gravity_ecef_mps2

EPOCH = dt.datetime(2026, 9, 11, 1, 42, 42, tzinfo=dt.timezone.utc)
# a Starlink-like orbit: 550 km circular, 53 degrees
R0_M = 6928.137e3
INC = np.radians(53.0)


def _integrated_orbit(t_s: np.ndarray, extra_mps2: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """EME2000 states at t_s from a numerically integrated orbit: zonal gravity about the
    true pole plus, when asked, an along-track acceleration the interpolator does not model."""
    m, _ = eme2000_to_teme_matrix(EPOCH, np.array([0.0]), 0.0)
    m = m[0]
    v0 = np.sqrt(3.986004418e14 / R0_M)

    def rhs(_, y):
        r, v = y[:3], y[3:]
        a = m.T @ gravity_ecef_mps2((m @ r)[None])[0] + extra_mps2 * v / np.linalg.norm(v)
        return np.concatenate([v, a])
    y0 = np.array([R0_M, 0, 0, 0, v0 * np.cos(INC), v0 * np.sin(INC)])
    sol = solve_ivp(rhs, (0, float(t_s[-1])), y0, method="DOP853", rtol=1e-12, atol=1e-6, t_eval=t_s)
    return sol.y[:3].T, sol.y[3:].T


def _covariance_uvw(n: int) -> np.ndarray:
    """Positive definite UVW covariances (m^2 ...) growing along the file like the operator's."""
    rng = np.random.default_rng(7)
    base = rng.standard_normal((6, 6)) * np.array([0.5, 2.0, 0.4, 1e-3, 5e-4, 1e-3])[:, None]
    p0 = base @ base.T + np.diag([0.4, 0.8, 1.2, 2e-6, 1e-6, 5e-6])
    growth = 1.0 + np.arange(n)[:, None, None] / n
    return p0[None] * growth


def _ephemeris(step_s: float = 60.0, n: int = 31, extra_mps2: float = 0.0, name: str = "STARLINK-99001"
               ) -> OperatorEphemeris:
    t = np.arange(n) * step_s
    r, v = _integrated_orbit(t, extra_mps2)
    eph = OperatorEphemeris("<fixture>", name, EPOCH + dt.timedelta(minutes=13), EPOCH,
                            EPOCH + dt.timedelta(seconds=float(t[-1])), step_s, "blend", "UVW",
                            (t * 1000).astype(np.int64), r, v, _covariance_uvw(n))
    # the file's resolution (0.1 mm, 1e-7 m/s, 11 digits): what a written file holds
    return parse_text(write_text(eph), "<fixture>", name)


# --------------------------------------------------------------------------- round trip


def test_written_fixture_round_trips_exactly(tmp_path):
    eph = _ephemeris()
    text = write_text(eph)
    again = parse_text(text, "again", eph.name)
    assert write_text(again) == text
    for f in ("t_ms", "r_eme2000_m", "v_eme2000_mps", "cov_uvw"):
        np.testing.assert_array_equal(getattr(again, f), getattr(eph, f))
    assert (again.start_utc, again.stop_utc, again.step_s, again.created_utc) == \
        (eph.start_utc, eph.stop_utc, eph.step_s, eph.created_utc)
    lines = text.splitlines()
    assert lines[1] == "ephemeris_start:2026-09-11 01:42:42 UTC ephemeris_stop:2026-09-11 02:12:42 UTC step_size:60"
    assert lines[4].startswith("2026254014242.000 6928.1370000000 ")      # day 254 of 2026, km
    assert len(lines) == 4 + 4 * len(eph) and all(len(lines[5 + 4 * k + j].split()) == 7
                                                  for k in range(len(eph)) for j in range(3))
    # through a folder and its manifest, by object name
    write_file(eph, tmp_path, serial=1)
    write_file(_ephemeris(name="STARLINK-99002"), tmp_path, serial=2)
    got = load_folder(tmp_path)
    assert got.names == ["STARLINK-99001", "STARLINK-99002"] and not got.rejected
    assert write_text(got.ephemerides["STARLINK-99001"]) == text
    assert load_folder(tmp_path, names=["STARLINK-99002"]).names == ["STARLINK-99002"]


def test_units_are_si_and_the_covariance_is_the_lower_triangle_row_by_row():
    eph = _ephemeris(n=2)
    lines = write_text(eph).splitlines()
    values = [float(x) for x in " ".join(lines[5:8]).split()]
    rows, cols = np.tril_indices(6)
    for k, (i, j) in enumerate(zip(rows, cols)):     # c11 c21 c22 c31 ... in km units
        assert eph.cov_uvw[0, i, j] == pytest.approx(values[k] * 1e6, rel=1e-9)
        assert eph.cov_uvw[0, j, i] == eph.cov_uvw[0, i, j]
    assert float(lines[4].split()[1]) * 1e3 == pytest.approx(eph.r_eme2000_m[0, 0], abs=1e-4)
    assert float(lines[4].split()[4]) * 1e3 == pytest.approx(eph.v_eme2000_mps[0, 0], abs=1e-7)


# --------------------------------------------------------------------------- interpolation


def test_interpolation_between_samples_is_far_below_a_metre_against_an_integrated_orbit():
    # the integrated truth carries an along-track 2e-5 m/s^2 (drag-like) that the
    # interpolator's acceleration leaves out
    eph = _ephemeris(n=61, extra_mps2=2e-5)
    t_mid = np.arange(len(eph) - 1) * 60.0 + 30.0
    t_q = np.concatenate([t_mid, t_mid - 17.0])
    r_true, v_true = _integrated_orbit(np.sort(np.concatenate([[0.0], t_q])), 2e-5)
    order = np.argsort(t_q)
    r, v, _, inside = interpolate_eme2000(eph, t_q[order])
    assert inside.all()
    err_r = np.linalg.norm(r - r_true[1:], axis=1)
    err_v = np.linalg.norm(v - v_true[1:], axis=1)
    assert err_r.max() < 0.01, err_r.max()          # 1 cm; the requirement is 1 m
    assert err_v.max() < 1e-3, err_v.max()          # 1 mm/s
    # at the records it returns the records
    r_n, v_n, _, _ = interpolate_eme2000(eph, eph.t_ms * 1e-3)
    np.testing.assert_allclose(r_n, eph.r_eme2000_m, atol=1e-6)
    np.testing.assert_allclose(v_n, eph.v_eme2000_mps, atol=1e-9)


def test_interpolated_ecef_states_match_a_dense_sgp4_orbit(tmp_path):
    """End to end: an SGP4 orbit sampled at 60 s, written in the operator's format (EME2000
    km), read back and interpolated to ECEF at the mid-points, against SGP4 there."""
    from leonav_runtime.orbits.elements import parse_elements_text
    from leonav_runtime.orbits.propagate import propagate_ecef
    tle = ("STARLINK-1008\n"
           "1 44714U 19074B   26254.07000000  .00001500  00000-0  10000-3 0  9990\n"
           "2 44714  53.0540 120.1234 0001400  90.0000 270.1000 15.06400000 12345\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        elements = parse_elements_text(tle, "fixture", strict_checksum=False)
    t_nodes = np.arange(0.0, 3601.0, 60.0)
    made = ephemerides_from_elements(elements, EPOCH, t_nodes, _covariance_uvw(t_nodes.size))
    path = write_file(made.ephemerides["STARLINK-1008"], tmp_path)
    got = load_folder(tmp_path)
    assert got.ephemerides["STARLINK-1008"].source == str(path)
    t_mid = t_nodes[:-1] + 30.0
    states = operator_states_ecef(got, ["STARLINK-1008"], EPOCH, t_mid)
    ref = propagate_ecef(elements, EPOCH, t_mid, acceleration=True, warn_stale=False)
    err = np.linalg.norm(states.r_ecef_m[0] - ref.r_ecef_m[0], axis=1)
    assert states.ok.all() and err.max() < 1.0, err.max()
    with pytest.raises(UserInputError, match="evenly spaced"):
        ephemerides_from_elements(elements, EPOCH, np.array([0.0, 60.0, 130.0]), np.eye(6))
    # SGP4's velocity is not the derivative of its position to better than ~0.01 m/s (python-sgp4
    # TEME, central differences of 0.01 s: 0.009-0.013 m/s on this orbit); the file carries both
    assert np.linalg.norm(states.v_ecef_mps[0] - ref.v_ecef_mps[0], axis=1).max() < 0.05
    assert np.abs(states.a_ecef_mps2[0] - ref.a_ecef_mps2[0]).max() < 1e-3


# --------------------------------------------------------------------------- frames, covariance


def test_eme2000_to_ecef_agrees_with_skyfield():
    framelib = pytest.importorskip("skyfield.framelib")
    from skyfield.api import load
    ts = load.timescale(builtin=True)
    eph = _ephemeris(n=3)
    for k, t in enumerate((0.0, 60.0, 120.0)):
        st = ts.from_datetime(EPOCH + dt.timedelta(seconds=t))
        # the same UT1 and no polar motion on both sides: the comparison is of the rotations
        r_e, _ = eme2000_to_ecef(eph.r_eme2000_m[k:k + 1], eph.v_eme2000_mps[k:k + 1], EPOCH, np.array([t]),
                                 ut1_utc_s=float(st.dut1), xp_rad=0.0, yp_rad=0.0)
        r_ref = framelib.itrs.rotation_at(st) @ (framelib.ICRS_to_J2000.T @ eph.r_eme2000_m[k])
        assert np.linalg.norm(r_e[0] - r_ref) < 0.01     # 1 cm at 6928 km (0.3 mas)
    # and the inverse undoes it
    t = eph.t_ms * 1e-3
    r_e, v_e = eme2000_to_ecef(eph.r_eme2000_m, eph.v_eme2000_mps, EPOCH, t)
    r_b, v_b = ecef_to_eme2000(r_e, v_e, EPOCH, t)
    np.testing.assert_allclose(r_b, eph.r_eme2000_m, atol=1e-6)
    np.testing.assert_allclose(v_b, eph.v_eme2000_mps, atol=1e-9)


def test_radial_only_covariance_maps_to_the_radial_direction_and_keeps_its_eigenvalues():
    eph = _ephemeris(n=3)
    sigma = 3.0
    cov = np.zeros((len(eph), 6, 6))
    cov[:, 0, 0] = sigma ** 2
    eph.cov_uvw = cov
    states = operator_states_ecef(OperatorEphemerisSet({eph.name: eph}), [eph.name], EPOCH, np.array([0.0, 60.0]))
    for k in range(2):
        p = states.cov_ecef[0, k]
        u = states.r_ecef_m[0, k] / np.linalg.norm(states.r_ecef_m[0, k])
        np.testing.assert_allclose(p[0:3, 0:3], sigma ** 2 * np.outer(u, u), atol=1e-9)
    # in-track variance lies along the velocity (circular orbit: V is the velocity direction)
    q = uvw_axes(eph.r_eme2000_m, eph.v_eme2000_mps)
    vhat = eph.v_eme2000_mps / np.linalg.norm(eph.v_eme2000_mps, axis=1, keepdims=True)
    assert np.einsum("ni,ni->n", q[:, :, 1], vhat).min() > 0.9999
    # a positive radial / in-track correlation stays positive along r and v (the axes' signs)
    corr = np.zeros((len(eph), 6, 6))
    corr[:, 0:2, 0:2] = [[4.0, 3.0], [3.0, 9.0]]
    p_eme = uvw_to_frame(corr, eph.r_eme2000_m, eph.v_eme2000_mps)
    rhat = eph.r_eme2000_m / np.linalg.norm(eph.r_eme2000_m, axis=1, keepdims=True)
    np.testing.assert_allclose(np.einsum("ni,nij,nj->n", rhat, p_eme[:, 0:3, 0:3], vhat), 3.0, rtol=1e-3)
    # a full covariance keeps its eigenvalues through the rotations (position block in ECEF)
    full = _ephemeris(n=3)
    p_eme = uvw_to_frame(full.cov_uvw, full.r_eme2000_m, full.v_eme2000_mps)
    np.testing.assert_allclose(np.linalg.eigvalsh(p_eme), np.linalg.eigvalsh(full.cov_uvw), rtol=1e-9)
    st_full = operator_states_ecef(OperatorEphemerisSet({full.name: full}), [full.name], EPOCH, np.array([0.0]))
    np.testing.assert_allclose(np.linalg.eigvalsh(st_full.cov_ecef[0, 0, 0:3, 0:3]),
                               np.linalg.eigvalsh(full.cov_uvw[0, 0:3, 0:3]), rtol=1e-9)
    # between records: the linear blend of the two UVW covariances
    _, _, c_mid, _ = interpolate_eme2000(full, np.array([15.0]))
    np.testing.assert_allclose(c_mid[0], 0.75 * full.cov_uvw[0] + 0.25 * full.cov_uvw[1], rtol=1e-12)


# --------------------------------------------------------------------------- hostile files


def _hostile(edit) -> str:
    lines = write_text(_ephemeris(n=4)).splitlines()
    return "\n".join(edit(lines)) + "\n"


def _set(lines, i, text):
    lines = list(lines)
    lines[i] = text
    return lines


HOSTILE = {
    # (edit of the fixture's lines, the 1-based line the message must name, words it must contain)
    "cut inside a record": (lambda ls: ls[:10], 11, "file ends inside the record of line 9"),
    "cut at a record boundary": (lambda ls: ls[:12], 12, "truncated"),
    "garbled number": (lambda ls: _set(ls, 5, ls[5].replace("e", "x", 1)), 6, "field 1 (c11)"),
    "garbled state": (lambda ls: _set(ls, 4, ls[4].replace(" 6928.137", " 6928.1x7")), 5,
                      "field 2 (x)"),
    "underscore in a number": (lambda ls: _set(ls, 4, ls[4].replace(" 6928.137", " 6_928.137")), 5,
                               "field 2 (x) '6_928.1370000000' is not a finite number"),
    "epochs out of order": (lambda ls: ls[:4] + ls[8:12] + ls[4:8] + ls[12:], 9, "not after the previous"),
    "covariance number missing": (lambda ls: _set(ls, 6, " ".join(ls[6].split()[:6])), 7, "expected 7 numbers"),
    "covariance line missing": (lambda ls: ls[:7] + ls[8:], 8, "found a state line where covariance line 3"),
    "records past the stop": (lambda ls: _set(ls, 1, ls[1].replace("ephemeris_stop:2026-09-11 01:45:42",
                                                                   "ephemeris_stop:2026-09-11 01:44:42")), 17,
                              "after the header's ephemeris_stop"),
    "record missing": (lambda ls: ls[:8] + ls[12:], 9, "expected the header's step_size"),
    "bad epoch": (lambda ls: _set(ls, 4, "2026367014242.000" + ls[4][17:]), 5, "out of range"),
    "bad step": (lambda ls: _set(ls, 1, ls[1].replace("step_size:60", "step_size:-1")), 2, "positive"),
    "other frame": (lambda ls: _set(ls, 3, "TEME"), 4, "expected one of UVW"),
    "header cut": (lambda ls: ls[:2], 3, "inside the header"),
    "negative variance": (lambda ls: _set(ls, 5, "-" + ls[5]), 6, "negative"),
}


@pytest.mark.parametrize("case", sorted(HOSTILE))
def test_hostile_file_is_refused_in_one_line_naming_the_line(case):
    edit, line, words = HOSTILE[case]
    with pytest.raises(UserInputError) as info:
        parse_text(_hostile(edit), "eph.txt")
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"eph.txt line {line}:"), message
    assert words in message, message


def test_a_file_over_the_size_limit_is_refused_before_reading(tmp_path, monkeypatch):
    from leonav_runtime.orbits.operator_ephemeris import load_file
    path = write_file(_ephemeris(n=4), tmp_path)
    monkeypatch.setenv("LEONAV_MAX_ELEMENT_MB", "0.001")
    with pytest.raises(UserInputError, match=r"0\.0 MB is more than the orbit-file limit of 0\.001 MB"):
        load_file(path)


def test_a_folder_loads_the_good_files_and_counts_the_bad(tmp_path):
    write_file(_ephemeris(name="STARLINK-99001"), tmp_path, serial=1)
    bad = write_file(_ephemeris(name="STARLINK-99002"), tmp_path, serial=2)
    bad.write_text(bad.read_text()[:-200])
    with pytest.warns(RejectedEphemerisWarning, match="1 operator-ephemeris file"):
        got = load_folder(tmp_path)
    assert got.names == ["STARLINK-99001"]
    assert len(got.rejected) == 1 and bad.name in got.rejected[0][1] and "line" in got.rejected[0][1]
    bad.write_bytes(b"created:\xff\n")
    (tmp_path / "MANIFEST.txt").write_text(bad.name + "\n")
    with pytest.raises(UserInputError, match="no usable operator ephemeris.*not ASCII"), \
            pytest.warns(RejectedEphemerisWarning):
        load_folder(tmp_path)


def test_wrong_satellite_or_time_span_is_one_clear_line():
    eph = _ephemeris(n=4)
    held = OperatorEphemerisSet({eph.name: eph})
    with pytest.raises(UserInputError) as info:
        operator_states_ecef(held, ["STARLINK-1234"], EPOCH, np.array([0.0, 60.0]))
    assert "\n" not in str(info.value) and "STARLINK-1234" in str(info.value) and eph.name in str(info.value)
    with pytest.raises(UserInputError, match="cover none of the 1 requested satellites over 2026-09-12"):
        operator_states_ecef(held, [eph.name], EPOCH, np.array([86400.0]))
    # partly covered: the covered satellite and times carry on, the rest is NaN and counted
    with pytest.warns(OperatorCoverageWarning, match="2 of 2 satellites not covered"):
        st = operator_states_ecef(held, [eph.name, "STARLINK-1234"], EPOCH, np.array([0.0, 170.0, 200.0]))
    assert not st.ok.any() and np.isfinite(st.r_ecef_m[0, :2]).all() and np.isnan(st.r_ecef_m[0, 2]).all()
    assert np.isnan(st.r_ecef_m[1]).all() and "2 of 3 requested times" not in st.failures[0][1]
    assert "1 of 3 requested times" in st.failures[0][1]


def test_the_gridded_rotation_matches_the_direct_one():
    from leonav_runtime.orbits import eme2000
    t = np.random.default_rng(1).uniform(0.0, 3 * 86400.0, 5000)
    m, gmst = eme2000.eme2000_to_teme_matrix(EPOCH, t, 0.05)
    m_direct, gmst_direct = eme2000._teme_matrix_direct(EPOCH, t, np.full(t.shape, 0.05))
    assert np.abs(m - m_direct).max() < 2e-12 and np.abs(gmst - gmst_direct).max() < 1e-13


def test_operator_states_replace_sgp4_where_a_file_covers_the_satellite():
    from leonav_runtime.orbits.elements import parse_elements_text
    from leonav_runtime.orbits.operator_states import operator_sat_states
    from leonav_runtime.orbits.propagate import propagate_ecef
    tle = ("STARLINK-1008\n"
           "1 44714U 19074B   26254.07000000  .00001500  00000-0  10000-3 0  9990\n"
           "2 44714  53.0540 120.1234 0001400  90.0000 270.1000 15.06400000 12345\n"
           "STARLINK-1009\n"
           "1 44715U 19074C   26254.07000000  .00001500  00000-0  10000-3 0  9991\n"
           "2 44715  53.0540 120.1234 0001400  90.0000 280.1000 15.06400000 12345\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        elements = parse_elements_text(tle, "fixture", strict_checksum=False)
        t_nodes = np.arange(0.0, 601.0, 60.0)
        sgp4 = propagate_ecef(elements, EPOCH, t_nodes, acceleration=False, warn_stale=False)
    # the operator's orbit of the first satellite: SGP4's, 100 m higher
    r0 = sgp4.r_ecef_m[0] * (1.0 + 100.0 / np.linalg.norm(sgp4.r_ecef_m[0], axis=1, keepdims=True))
    r_eme, v_eme = ecef_to_eme2000(r0, sgp4.v_ecef_mps[0], EPOCH, t_nodes)
    eph = OperatorEphemeris("op", "STARLINK-1008", None, EPOCH, EPOCH + dt.timedelta(seconds=600), 60.0, "x", "UVW",
                            (t_nodes * 1000).astype(np.int64), r_eme, v_eme, _covariance_uvw(t_nodes.size))
    t = np.array([30.0, 200.0, 570.0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        states, used = operator_sat_states(OperatorEphemerisSet({eph.name: eph}), elements, EPOCH, t)
        ref = propagate_ecef(elements, EPOCH, t, warn_stale=False)
    assert used.tolist() == [True, False] and states.r_ecef_m.shape == (2, 3, 3)
    lift = np.linalg.norm(states.r_ecef_m[0], axis=1) - np.linalg.norm(ref.r_ecef_m[0], axis=1)
    assert np.abs(lift - 100.0).max() < 1.0                       # the operator's orbit, not SGP4's
    np.testing.assert_array_equal(states.r_ecef_m[1], ref.r_ecef_m[1])
    # past the file's end the satellite keeps SGP4 (counted in the mask)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        _late, used_late = operator_sat_states(OperatorEphemerisSet({eph.name: eph}), elements, EPOCH, t + 60.0)
    assert not used_late.any()


def test_a_join_of_two_arcs_is_found_and_not_interpolated_across():
    from leonav_runtime.orbits.operator_states import discontinuities
    eph = _ephemeris(n=11)
    assert discontinuities(eph) == []
    # from record 6 on, another arc of the same orbit 300 m further along it (the operator's
    # "blend" files are reported to join two arcs at 48 h, a few hundred metres apart)
    r2, v2 = _integrated_orbit(eph.t_ms[6:] * 1e-3 + 300.0 / 7590.0)
    eph.r_eme2000_m[6:], eph.v_eme2000_mps[6:] = r2, v2
    assert discontinuities(eph) == [5 + 4 * 6]                  # the line of record 6
    t = np.array([30.0, 5 * 60.0 + 30.0, 8 * 60.0 + 30.0])
    r, _, _, inside = interpolate_eme2000(eph, t)
    assert inside.tolist() == [True, False, True] and np.isnan(r[1]).all()
    r_true, _ = _integrated_orbit(np.array([0.0, 30.0]))
    assert np.linalg.norm(r[0] - r_true[1]) < 0.01
    with pytest.warns(OperatorCoverageWarning, match="between two arcs"):
        st = operator_states_ecef(OperatorEphemerisSet({eph.name: eph}), [eph.name], EPOCH, t)
    assert "new arc at line 29" in st.failures[0][1] and np.isfinite(st.r_ecef_m[0, [0, 2]]).all()
    # a record whose velocity disagrees with its positions by 16 m/s spoils both its intervals
    odd = _ephemeris(n=11)
    odd.v_eme2000_mps[6] += 16.0 * odd.v_eme2000_mps[6] / np.linalg.norm(odd.v_eme2000_mps[6])
    assert discontinuities(odd) == [29, 33]
