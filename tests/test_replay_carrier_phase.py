"""The road from the tracker's carrier phase to the filter for recorded data (`leo-phase` replay).

The differencing (`inputs.carrier_phase`) on hand-made epochs, the tone-offset reference to
the channel centre against an exact pass, and a replay of a synthetic session whose capture
tones are the exact integral of their baseband frequency (`beacons.synth`), checked against
that truth. (The synthesizer's Doppler has no light time and no per-tone scaling, so the
filter's model is not checked against it here: tests/test_carrier_phase_filter.py does that
against `simulation/carrier_truth.py`.)
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gen.constants import C_LIGHT_MPS, COMB_SPACING_HZ, STARLINK_BEACON_HZ
from leonav_runtime.inputs import BREAK_REASONS, phase_differences, tone_to_centre


def _epochs():
    """Two tones; tone (7, 10) has one break of each reason, tone (8, 11) none. Returned shuffled."""
    t = np.round(np.arange(10) * 0.1, 10)
    t[8:] += 0.15                          # epochs 7 -> 8: 0.25 s apart (a gap)
    phi = 1000.0 + 37.25 * np.arange(10) ** 2
    sig = 0.01 + 0.001 * np.arange(10)
    locked = np.ones(10, bool)
    locked[3] = False                      # pairs (2,3) and (3,4): unlocked
    phi[5] = np.nan                        # pairs (4,5) and (5,6): non-finite
    arc = np.zeros(10, int)
    arc[7:] = 1                            # pair (6,7): new arc; (7,8): gap; (8,9): good
    a = dict(t=t, sat=np.full(10, 7), tone=np.full(10, 10), phi=phi, sig=sig, lk=locked, arc=arc)
    tb = np.round(np.arange(4) * 0.1 + 0.003, 10)   # 3 ms off the grid: inside the 5 ms tolerance
    b = dict(t=tb, sat=np.full(4, 8), tone=np.full(4, 11), phi=np.array([5.0, 4.0, 2.5, -1.0]),
             sig=np.full(4, 0.02), lk=np.ones(4, bool), arc=np.full(4, 3))
    cols = {k: np.concatenate([a[k], b[k]]) for k in a}
    order = np.random.default_rng(0).permutation(14)
    return {k: v[order] for k, v in cols.items()}, a, b


def test_differences_are_exact_and_every_break_is_counted():
    e, a, b = _epochs()
    d = phase_differences(e["t"], e["sat"], e["tone"], e["phi"], e["sig"], e["lk"], e["arc"], epoch_s=0.1)
    c = d.counts
    assert c["tones"] == 2 and c["epochs"] == 14 and c["pairs"] == 12
    assert c["breaks"] == {"unlocked": 2, "non_finite": 2, "new_arc": 1, "gap": 1}
    assert set(c["breaks"]) == set(BREAK_REASONS)
    assert c["differences"] + sum(c["breaks"].values()) == c["pairs"]
    # tone A: pairs (0,1), (1,2), (8,9); tone B: all three
    good_a = [(0, 1), (1, 2), (8, 9)]
    want_t = [a["t"][k] for _, k in good_a] + list(b["t"][1:])
    want_z = [a["phi"][k] - a["phi"][j] for j, k in good_a] + list(np.diff(b["phi"]))
    want_s = [math.hypot(a["sig"][k], a["sig"][j]) for j, k in good_a] + [math.hypot(0.02, 0.02)] * 3
    want_dt = [a["t"][k] - a["t"][j] for j, k in good_a] + list(np.diff(b["t"]))
    np.testing.assert_array_equal(d.t, want_t)
    np.testing.assert_array_equal(d.z_cycles, want_z)
    np.testing.assert_allclose(d.sigma_cycles, want_s, rtol=1e-15)
    np.testing.assert_allclose(d.interval_s, want_dt, rtol=1e-12)
    np.testing.assert_allclose(d.t_prev, d.t - d.interval_s)
    np.testing.assert_array_equal(d.norad_id, [7, 7, 7, 8, 8, 8])
    np.testing.assert_array_equal(d.tone_id, [10, 10, 10, 11, 11, 11])


def test_tolerance_and_a_zero_sigma_are_breaks_and_bad_columns_one_line():
    t = np.array([0.0, 0.1, 0.2, 0.3])
    one = dict(norad_id=np.ones(4, int), tone_id=np.ones(4, int), phase_cycles=np.arange(4.0),
               locked=np.ones(4, bool), arc=np.zeros(4, int))
    d = phase_differences(t + np.array([0, 0, 0.006, 0]), sigma_phase_cycles=np.full(4, 0.01), epoch_s=0.1, **one)
    assert d.counts["breaks"]["gap"] == 2 and d.counts["differences"] == 1      # 6 ms off: outside 5 ms
    d = phase_differences(t, sigma_phase_cycles=np.array([0.01, 0.0, 0.01, 0.01]), epoch_s=0.1, **one)
    assert d.counts["breaks"]["non_finite"] == 2 and d.counts["differences"] == 1
    with pytest.raises(UserInputError, match="phase_cycles: shape \\(3,\\), expected \\(4,\\)"):
        phase_differences(t, sigma_phase_cycles=np.full(4, 0.01), epoch_s=0.1,
                          **(one | {"phase_cycles": np.zeros(3)}))
    with pytest.raises(UserInputError, match="epoch_s"):
        phase_differences(t, sigma_phase_cycles=np.full(4, 0.01), epoch_s=0.0, **one)


def test_an_outer_tone_referred_to_the_centre_holds_to_3e_3_cycles():
    """An exact pass: tone k = 4 at f_c + 4 x spacing, a receiver driving at 30 m/s, an LO
    offset of 2 MHz; the centre's phase change recovered from the tone's with the range change
    predicted for a receiver at rest at the origin."""
    from leonav_runtime.orbits import propagate_ecef
    from leonav_runtime.orbits.geometry import geodetic_to_ecef
    from leonav_runtime.simulation.session_synth import PAPER_EPOCH, builtin_starlink

    es = builtin_starlink(PAPER_EPOCH)
    r0 = geodetic_to_ecef(math.radians(43.08), math.radians(-77.68), 170.0)
    T, f_c, b_lo, df = 0.1, STARLINK_BEACON_HZ, 2e6, 4 * COMB_SPACING_HZ
    t = np.arange(0.0, 60.0, T)
    up = r0 / np.linalg.norm(r0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        coarse = propagate_ecef(es, PAPER_EPOCH, t[::100]).r_ecef_m - r0
        elev = np.einsum("ijk,k->ij", coarse / np.linalg.norm(coarse, axis=2)[..., None], up)
        i = int(np.argmax(elev.min(axis=1)))        # the satellite highest over the whole minute
        r_s = propagate_ecef(es.select([i]), PAPER_EPOCH, t).r_ecef_m[0]
    east = np.cross([0.0, 0.0, 1.0], up)
    r_u = r0 + 30.0 * t[:, None] * east / np.linalg.norm(east)
    rho = np.linalg.norm(r_s - r_u, axis=1)
    phase_tone = (df + b_lo) * t - (f_c + df) / C_LIGHT_MPS * rho
    centre = np.diff(b_lo * t - f_c / C_LIGHT_MPS * rho)
    drho_pred = np.diff(np.linalg.norm(r_s - r0, axis=1))
    got = tone_to_centre(np.diff(phase_tone), np.diff(t), df, drho_pred)
    assert np.max(np.abs(got - centre)) < 3e-3
    # what is corrected matters: the offset alone leaves (df/c) drho, and rescaling z by
    # f_c/(f_c + df) leaves T b_lo df/f_c
    assert np.max(np.abs(np.diff(phase_tone) - T * df - centre)) > 0.1
    assert np.max(np.abs(np.diff(phase_tone - df * t) * f_c / (f_c + df) - centre)) > 1.0


@pytest.fixture(scope="module")
def phase_replay(tmp_path_factory):
    from leonav_runtime.replay import ReplayOptions, replay_session
    from leonav_runtime.replay.run import decode_inputs
    from leonav_runtime.simulation import session_synth as ss

    cfg = ss.SynthSessionConfig(seconds=6.0, seed=4, imu_rate_hz=50.0, imu_baud=115200, n_satellites=4)
    base = tmp_path_factory.mktemp("phase")
    synth = ss.write_synthetic_session(base / "s", cfg)
    opts = ReplayOptions(modes=("leo-phase+imu", "leo-phase+alpha+imu"), gnss_latency_s=cfg.gnss_latency_s)
    inputs = decode_inputs(synth.folder, opts, synth.elements, base / "out")
    metrics = replay_session(synth.folder, base / "out", opts, synth.elements, inputs=inputs)
    return synth, inputs, metrics


def test_replay_table_is_the_capture_truth_phase_difference(phase_replay):
    from leonav_runtime.beacons import synth as bs
    from leonav_runtime.simulation import session_synth as ss

    synth, inputs, _ = phase_replay
    tab = inputs.satellites["carrier_phase"]
    _, scfg, site, start = ss.capture_config(synth.cfg)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        truth = bs.build_truth(synth.elements, site, start, scfg)
    t0 = (inputs.beacons["capture_start_utc"] - inputs.epoch_utc).total_seconds()   # capture time = t - t0
    assert set(np.unique(tab.sat_id)) == set(truth.norad_ids.tolist())
    for i, nid in enumerate(truth.norad_ids):
        sel = tab.sat_id == nid
        phi = CubicSpline(truth.t_grid_s, truth.baseband_hz[i]).antiderivative()
        tau = tab.t[sel] - t0
        resid = tab.z[sel] - (phi(tau) - phi(tau - tab.interval_s[sel]))
        assert sel.sum() > 40
        assert np.sqrt(np.mean(resid ** 2)) < 0.02 and abs(resid.mean()) < 0.004        # tracker noise ~0.01
        assert 0.5 < np.std(resid / tab.sigma[sel]) < 2.0
    np.testing.assert_allclose(tab.interval_s, 0.1, atol=0.005)
    # the satellite at both ends is the SGP4 state of its element set: 0.1 s of its flight apart
    step = np.linalg.norm(tab.sat_ecef[:, :3] - tab.sat_prev_r_m, axis=1) / tab.interval_s
    np.testing.assert_allclose(step, np.linalg.norm(tab.sat_ecef[:, 3:6], axis=1), rtol=2e-3)


def test_replay_runs_the_phase_modes_and_reports_the_counts(phase_replay):
    _, inputs, metrics = phase_replay
    c = inputs.counts["carrier_phase"]
    assert c["tones_tracked"] == 4 and c["tones_without_comb_index"] == 0
    assert c["pairs"] == c["epochs"] - c["tones_tracked"]
    assert c["differences"] + sum(c["breaks"].values()) == c["pairs"]
    assert c["differences"] == inputs.satellites["carrier_phase"].t.size > 150
    assert any(n.startswith("carrier phase: 4 tone(s) tracked") for n in metrics["notes"])
    assert metrics["beacons"]["carrier_phase"]["differences"] == c["differences"]
    assert set(metrics["modes"]) == {"leo-phase+imu", "leo-phase+alpha+imu"}
    assert inputs.records["carrier_phase"].size > 0
    assert not metrics["skipped_modes"]


def test_phase_mode_without_a_capture_is_skipped_with_its_reason(phase_replay, tmp_path):
    import shutil

    from leonav_runtime.replay import ReplayOptions
    from leonav_runtime.replay.run import decode_inputs

    synth, _, _ = phase_replay
    folder = tmp_path / "s"
    shutil.copytree(synth.folder, folder, ignore=shutil.ignore_patterns("sdr.cu8"))
    inputs = decode_inputs(folder, ReplayOptions(modes=("leo-phase+imu", "fix+imu")), synth.elements)
    assert inputs.skipped == {"leo-phase+imu": "no carrier-phase difference inside the IMU time span: "
                                               "no sdr.cu8 in the session"}
    assert "carrier_phase" not in inputs.counts


def test_the_phase_table_takes_both_ends_from_operator_files_and_refers_tones_to_the_centre():
    """Satellite 0 has an operator file 1 km ahead of its element set, satellite 1 none; the
    second record is a tone 4 comb steps above the centre."""
    from leonav_runtime.inputs import PhaseDifferences
    from leonav_runtime.orbits import default_elements, propagate_ecef
    from leonav_runtime.orbits.geometry import geodetic_to_ecef
    from leonav_runtime.orbits.operator_states import ephemerides_from_elements
    from leonav_runtime.replay.beacon_table import PhaseMeasurements, carrier_phase_table
    from leonav_runtime.simulation.session_synth import PAPER_EPOCH

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        es = default_elements(PAPER_EPOCH)["starlink"]
        lead = 1000.0 / 7600.0
        made = ephemerides_from_elements(es.select([0]), PAPER_EPOCH + _timedelta(lead),
                                         np.arange(-120.0, 241.0, 60.0), np.diag([1.0, 1, 1, 1e-6, 1e-6, 1e-6]))
    for e in made.ephemerides.values():
        e.start_utc, e.stop_utc = e.start_utc - _timedelta(lead), e.stop_utc - _timedelta(lead)
    t = np.array([1.0, 2.0, 1.5])
    dt_s = np.full(3, 0.1)
    z_raw = np.array([-2000.0, -2000.0 + 0.1 * 4 * COMB_SPACING_HZ, -1500.0])
    d = PhaseDifferences(t, dt_s, es.norad_ids[[0, 0, 1]], np.array([1, 2, 3]), z_raw, np.full(3, 0.01), {})
    pm = PhaseMeasurements(d, np.array([0, 0, 1]), np.array([0.0, 4 * COMB_SPACING_HZ, 0.0]), {})
    r0 = geodetic_to_ecef(math.radians(43.08), math.radians(-77.68), 170.0)
    notes: list[str] = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with_files = carrier_phase_table(pm, es, PAPER_EPOCH, r0, made, notes)
        plain = carrier_phase_table(pm, es, PAPER_EPOCH, r0)
        sgp4_prev = propagate_ecef(es.select([1]), PAPER_EPOCH, [1.4]).r_ecef_m[0, 0]
    moved = np.linalg.norm(with_files.sat_ecef[:, :3] - plain.sat_ecef[:, :3], axis=1)
    moved_prev = np.linalg.norm(with_files.sat_prev_r_m - plain.sat_prev_r_m, axis=1)
    assert np.abs(moved[:2] - 1000.0).max() < 5.0 and np.abs(moved_prev[:2] - 1000.0).max() < 5.0
    np.testing.assert_array_equal(with_files.sat_ecef[2], plain.sat_ecef[2])
    np.testing.assert_allclose(plain.sat_prev_r_m[2], sgp4_prev, atol=1e-6)
    assert notes == ["beacons: carrier phase: 1 of 2 satellites' states from operator ephemerides, "
                     "1 from their element sets"]
    # the centre tone and the other satellite unchanged; tone 4: minus T df plus (df/c) x drho
    np.testing.assert_array_equal(plain.z[[0, 2]], z_raw[[0, 2]])
    drho = np.linalg.norm(plain.sat_ecef[1, :3] - r0) - np.linalg.norm(plain.sat_prev_r_m[1] - r0)
    assert plain.z[1] == pytest.approx(-2000.0 + 4 * COMB_SPACING_HZ / C_LIGHT_MPS * drho, abs=1e-9)
    assert abs(plain.z[1] + 2000.0) > 0.01            # the Doppler-scaling term: 0.046 cycles here
    plain.check()


def _timedelta(seconds: float):
    import datetime as dt

    return dt.timedelta(seconds=seconds)


def test_replay_phase_r_carries_the_operator_files_covariance(phase_replay, tmp_path):
    """With operator ephemerides the phase differences' R gets the files' orbit covariance too
    (J P J^T, J the phase's orbit Jacobian with both ends of the difference): 4x the files'
    covariance is 4x the added term, and the Doppler-rate's beside it."""
    from leonav_runtime.orbits.operator_ephemeris import write_file
    from leonav_runtime.orbits.operator_states import ephemerides_from_elements
    from leonav_runtime.replay import ReplayOptions
    from leonav_runtime.replay.run import decode_inputs
    from leonav_runtime.simulation.session_synth import PAPER_EPOCH

    synth = phase_replay[0]
    es = synth.elements
    es = es.select(np.flatnonzero(np.isin(es.norad_ids, synth.sdr_info["norad_ids"])))
    big = np.diag([0.46, 0.78, 1.21, 2.0e-6, 5.2e-7, 5.4e-6]) * 1e4     # 100x a public file's sigmas
    for name, cov in (("x1", big), ("x4", 4.0 * big)):
        made = ephemerides_from_elements(es, PAPER_EPOCH, np.arange(-120.0, 241.0, 60.0), cov)
        for k, e in enumerate(made.ephemerides.values()):
            write_file(e, tmp_path / name, serial=k)

    def records(folder, orbit_states=None):
        opts = ReplayOptions(modes=("leo-phase+alpha+imu",), operator_ephemerides=folder,
                             gnss_latency_s=synth.cfg.gnss_latency_s, orbit_states_sigma_m=orbit_states)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            inputs = decode_inputs(synth.folder, opts, synth.elements, tmp_path / "out")
        return inputs.records, inputs.notes
    base, _ = records(None)
    r1, notes = records(str(tmp_path / "x1"))
    r4, _ = records(str(tmp_path / "x4"))
    assert "beacons: doppler-rate and carrier-phase R + J P J^T of the operator covariance; 0 records without it" \
        in notes
    for kind in ("carrier_phase", "doppler_rate"):
        added = r1[kind]["R"] - base[kind]["R"]
        assert added.min() > 0, kind
        assert r4[kind]["R"] - base[kind]["R"] == pytest.approx(4.0 * added, rel=1e-6), kind
    # with --orbit-states the offsets are estimated instead: the files' covariance stays out of R
    rs, notes = records(str(tmp_path / "x1"), orbit_states=(1.4, 4.7, 2.2))
    assert any("the operator covariance is not added to R: --orbit-states" in n for n in notes)
    for kind in ("carrier_phase", "doppler_rate"):
        np.testing.assert_array_equal(rs[kind]["R"], base[kind]["R"])
    from leonav_runtime.common.errors import UserInputError
    from leonav_runtime.replay.options import check_options

    with pytest.raises(UserInputError, match="--orbit-states with --corrections"):
        check_options(ReplayOptions(orbit_states_sigma_m=(1.0, 1.0, 1.0), corrections="corr.txt"))


def test_the_sample_clock_scales_an_outer_tones_offset_and_h_carries_it():
    """A static receiver, tone k = 4, an SDR clock 100 ppm fast: the SDR counts the tone's phase
    on its own clock, (1 - s)(df t - ((f_c + df)/c) rho) + b_lo t. Referred to the centre, the
    change s makes to z is the change it makes to the generated h through the table's
    `tone_offset_hz` (aux `df_tone`): -s T df + s (f_c/c) drho, to 1e-3 cycles (2.5e-4 measured:
    s (f_c/c) times the light-time and Sagnac part of drho, which this geometric truth leaves
    out); h without the tone's offset misses by s T df = 1.76 cycles."""
    from leonav_runtime.core import navfuncs
    from leonav_runtime.gen import state_layout as L
    from leonav_runtime.inputs import CarrierPhaseTable
    from leonav_runtime.inputs.measurements import satellite_aux
    from leonav_runtime.orbits import propagate_ecef
    from leonav_runtime.orbits.geometry import geodetic_to_ecef
    from leonav_runtime.simulation.session_synth import PAPER_EPOCH, builtin_starlink

    from leonav_runtime.gen.registry import PARAMS

    nav = navfuncs.NavFunctions()
    p = np.array([q.example for q in sorted(PARAMS, key=lambda q: q.offset)], float)
    r0 = geodetic_to_ecef(p[L.P_LAT0_RAD], p[L.P_LON0_RAD], p[L.P_H0_M])
    T, f_c, b_lo, df, s = 0.1, p[L.P_F_C_HZ], 2e6, 4 * COMB_SPACING_HZ, 1e-4
    t = np.arange(0.0, 30.0 + T / 2, T)
    up = r0 / np.linalg.norm(r0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        es = builtin_starlink(PAPER_EPOCH)
        coarse = propagate_ecef(es, PAPER_EPOCH, t[::50]).r_ecef_m - r0
        elev = np.einsum("ijk,k->ij", coarse / np.linalg.norm(coarse, axis=2)[..., None], up)
        i = int(np.argmax(elev.min(axis=1)))
        st = propagate_ecef(es.select([i]), PAPER_EPOCH, t)
    r_s = st.r_ecef_m[0]
    rho = np.linalg.norm(r_s - r0, axis=1)

    def road(scale):
        phase = (1 - scale) * (df * t - (f_c + df) / C_LIGHT_MPS * rho) + b_lo * t
        return tone_to_centre(np.diff(phase), np.diff(t), df, np.diff(rho))
    sat = np.hstack([st.r_ecef_m[0], st.v_ecef_mps[0], st.a_ecef_mps2[0]])[1:]
    n = t.size - 1
    table = CarrierPhaseTable(t[1:], np.full(n, 7), road(s), 0.01, sat, None, np.diff(t), r_s[:-1], df).check()
    aux = satellite_aux(table, np.zeros((n, 3)), L)
    np.testing.assert_array_equal(aux[:, L.AUX_DF_TONE], df)
    x = np.zeros(L.NX)
    x[L.X_Q_NB] = 1.0
    x[L.X_B_LO] = b_lo

    def h(scale, aux_rows):
        xs = x.copy()
        xs[L.X_S_CLK] = scale
        return nav.h_many("carrier_phase", xs, aux_rows, p, jacobian=False)[0]
    want = road(s) - road(0.0)
    assert np.max(np.abs((h(s, aux) - h(0.0, aux)) - want)) < 1e-3
    centre = aux.copy()
    centre[:, L.AUX_DF_TONE] = 0.0
    assert np.min(np.abs((h(s, centre) - h(0.0, centre)) - want)) > 1.7


def test_replay_estimates_the_orbit_offsets_with_orbit_states(phase_replay, tmp_path, capsys):
    """`--orbit-states R,A,C` (ephemeris method 1 in the replay): the phase mode carries each
    tracked satellite's offsets as states. The synthetic capture's phase follows the element
    orbits themselves (no orbit error), so every estimated offset is within 3 sigma of zero, and
    the metrics name the satellites; a bad prior is one line naming the option."""
    from leonav_runtime.cli import main
    from leonav_runtime.core import navfuncs
    from leonav_runtime.replay.run import run_modes

    _, inputs, _ = phase_replay
    nav = navfuncs.NavFunctions()
    runs = run_modes(inputs, ("leo-phase+imu",), 10.83, nav, orbit_sigma_m=(240.0, 960.0, 170.0))
    orb = runs["leo-phase+imu"][1].orbit_states
    assert orb["no_slot"] == 0 and orb["slots_taken"] == len(orb["satellites"]) == 4
    for sat in orb["satellites"].values():
        off, sig = np.asarray(sat["offset_rac_m"]), np.asarray(sat["sigma_rac_m"])
        assert np.all(np.abs(off) < 3 * sig) and np.all(sig < [240.0, 960.0, 170.0])
    plain = run_modes(inputs, ("leo-phase+imu",), 10.83, nav)["leo-phase+imu"][1]
    assert plain.orbit_states is None
    assert main(["replay", str(tmp_path), "--orbit-states", "240,0,170"]) == 2
    assert "--orbit-states: (240.0, 0.0, 170.0): expected three sigmas > 0 m" in capsys.readouterr().err
    assert main(["replay", str(tmp_path), "--orbit-states", "240,x,170"]) == 2
    assert "--orbit-states: '240,x,170': expected three sigmas in m" in capsys.readouterr().err


def _along_shifted(es, sigma_m: float, rng) -> tuple:
    """(ElementSet, {NORAD id: shift m}): every satellite moved along its track by a normal draw of
    sigma_m (its mean anomaly advanced by shift / a): the true orbits of a session whose receiver
    believes `es`."""
    from sgp4.api import WGS72, Satrec

    from leonav_runtime.orbits.elements import ElementSet

    sats, shift = [], {}
    for s, nid in zip(es.satrecs, es.norad_ids.tolist()):
        d = float(rng.normal(0.0, sigma_m))
        moved = Satrec()
        moved.sgp4init(WGS72, "i", s.satnum, s.jdsatepoch + s.jdsatepochF - 2433281.5, s.bstar, s.ndot, s.nddot,
                       s.ecco, s.argpo, s.inclo, s.mo + d / (s.a * 6378135.0), s.no_kozai, s.nodeo)
        sats.append(moved)
        shift[nid] = d
    return ElementSet(list(es.names), es.norad_ids.copy(), list(es.epochs_utc), sats, list(es.sources),
                      constellation="starlink"), shift


def test_orbit_states_estimate_the_along_track_errors_from_the_capture_itself(tmp_path):
    """End to end on IQ: a synthetic session whose capture is made from orbits 300 m (1 sigma)
    along track from the element sets the replay is given. Without orbit states the phase
    differences disagree with the element orbits by up to ~1 cycle and a quarter of them are gated;
    with `--orbit-states 100,500,100` the filter estimates each satellite's along-track error
    (every estimate within 3 sigma of the truth's shift, the sigmas below the prior), gates few and
    ends closer to the truth. Measured: 57 -> 9 gated of 216 differences, final position error
    10.7 -> 5.9 m, RMSE 7.3 -> 5.0 m (a 6 s session)."""
    from leonav_runtime.replay import ReplayOptions, replay_session
    from leonav_runtime.replay.run import decode_inputs
    from leonav_runtime.simulation import session_synth as ss

    cfg = ss.SynthSessionConfig(seconds=6.0, seed=4, imu_rate_hz=50.0, imu_baud=115200, n_satellites=4)
    believed = ss.builtin_starlink(cfg.epoch_utc)
    true_orbits, shift = _along_shifted(believed, 300.0, np.random.default_rng(5))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        synth = ss.write_synthetic_session(tmp_path / "s", cfg, elements=true_orbits)
        out = {}
        for name, sig in (("plain", None), ("states", (100.0, 500.0, 100.0))):
            opts = ReplayOptions(modes=("leo-phase+imu",), gnss_latency_s=cfg.gnss_latency_s, orbit_states_sigma_m=sig)
            inputs = decode_inputs(synth.folder, opts, believed, tmp_path / name)
            out[name] = replay_session(synth.folder, tmp_path / name, opts, believed, inputs=inputs)["modes"]["leo-phase+imu"]
    plain, states = out["plain"], out["states"]
    assert states["records"]["gated"] < plain["records"]["gated"] / 3
    assert states["final_position_error_m"] < 0.7 * plain["final_position_error_m"]
    assert states["rmse_position_m"] < 0.8 * plain["rmse_position_m"]
    sats = states["orbit_states"]["satellites"]
    assert len(sats) == 4
    for nid, s in sats.items():
        along, sigma = s["offset_rac_m"][1], s["sigma_rac_m"][1]
        assert abs(along - shift[int(nid)]) < 3 * sigma and sigma < 500.0, (nid, along, sigma, shift[int(nid)])
    assert sum(s["offset_rac_m"][1] * shift[int(n)] for n, s in sats.items()) > 0   # the right way round
