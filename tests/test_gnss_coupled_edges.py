"""Edge cases of the tightly coupled GNSS road (review of issue 10): time tags of RXM-RAWX
without a valid leapS, gross pseudoranges, rows the filter cannot take, receiver clock
jumps inside gaps, and the start of the inter-system biases."""
from __future__ import annotations

import struct

import numpy as np

from leonav.hardware.clock import TimeMap
from leonav.hardware.gnss import ubx
from leonav.hardware.gnss.reader import GnssDecoder
from leonav.hardware.records import GnssTimeTag
from leonav_runtime.gnss import time as gtime


def _rawx(t_gps_s: float, leap_s: int, leap_valid: bool) -> bytes:
    week, tow = gtime.week_tow(t_gps_s)
    return ubx.build_frame(0x02, 0x15, struct.pack("<dHbBBB2x", float(tow), int(week), leap_s, 0,
                                                   0x01 if leap_valid else 0x00, 1))


def _tags(frames: list[tuple[bytes, float]]) -> list[GnssTimeTag]:
    dec = GnssDecoder()
    out = [r for data, t in frames for r in dec.decode(data, t)] + dec.close()
    return [r for r in out if isinstance(r, GnssTimeTag)]


def test_rawx_without_valid_leap_seconds_still_tags_time_on_the_gps_scale():
    """Before: no time tag, so with no NMEA the IMU axis fell back to the host clock while the
    pseudoranges sat on GPS time. Now the leap-second table gives GPS - UTC, and the tag's UTC
    maps back to the RAWX GPS time exactly as `coupled.gps_epoch` places the pseudoranges."""
    t_gps = gtime.gps_seconds(2300, 345600.25)     # 2024-02-07: GPS - UTC = 18 s
    valid = _tags([(_rawx(t_gps, 18, True), 10.0)])
    # leapS not valid yet: the receiver's (wrong) default leapS must not be used
    unsure = _tags([(_rawx(t_gps + k, 15, False), 10.0 + k) for k in range(5)])
    assert len(valid) == 1 and len(unsure) == 5
    assert unsure[0].utc == valid[0].utc
    for k, tag in enumerate(unsure):
        assert gtime.utc_to_gps_seconds(tag.utc) == t_gps + k
    tm = TimeMap.fit(unsure)
    assert tm.valid and tm.source == "RAWX"
    assert abs(tm.to_utc_unix(10.0) - valid[0].utc.timestamp()) < 1e-6


def _mutated_0759(changes: dict[tuple[int, int], str]):
    """0759 observations with C1 of (epoch, satellite line) replaced by F14.3 text."""
    from leonav_runtime.gnss.rinex_obs import parse_rinex_obs
    from tests.test_spp_bad_input import _first_epoch_lines, _texts

    obs_text, nav_text = _texts()
    lines, k = _first_epoch_lines(obs_text)
    for (epoch, sat), text in changes.items():
        i = k + epoch * 9 + 1 + sat     # 8 satellites per epoch in the first hour of 0759
        lines[i] = lines[i][:16] + f"{text:>14}" + lines[i][30:]
    from leonav_runtime.gnss.rinex_nav import parse_rinex_nav

    return parse_rinex_obs("\n".join(lines) + "\n", "mutated.05o"), parse_rinex_nav(nav_text, "07590920.05n")


def test_gross_pseudoranges_are_counted_implausible_and_their_epochs_solved():
    """Before: -2e7 m in one row pulled its epoch away and every row of it counted as below the
    elevation mask. Now the row alone is `implausible_pseudorange`, the epoch is solved from the
    others and lands where the clean epoch without that satellite does (within metres)."""
    from tests.test_spp_bad_input import _solve

    clean_obs, nf = _mutated_0759({})
    obs, _ = _mutated_0759({(0, 1): "-20000000.000", (1, 2): "60000000.000", (2, 3): "0.500"})
    clean, res = _solve(clean_obs, nf), _solve(obs, nf)
    assert res.counts["implausible_pseudorange"] == 3
    assert res.counts["below_elevation_mask"] == clean.counts["below_elevation_mask"]
    assert res.counts.get("epoch_without_solution", 0) == clean.counts.get("epoch_without_solution", 0)
    assert res.solved[:3].all() and list(res.ns[:3]) == [n - 1 for n in clean.ns[:3]]
    assert np.linalg.norm(res.r_ecef_m[:3] - clean.r_ecef_m[:3], axis=1).max() < 30.0
    assert np.array_equal(res.r_ecef_m[3:], clean.r_ecef_m[3:])
    # a sound pseudorange is never called implausible (the real hour: none flagged)
    assert "implausible_pseudorange" not in clean.counts


def test_a_row_the_filter_cannot_take_is_dropped_and_counted_not_fatal():
    """Before: a RAIM-excluded or unsolved row with a pseudorange <= 0 reached
    GnssObservationTable.check, whose error stopped every mode."""
    import datetime as dt

    from leonav_runtime.gnss import coupled
    from leonav_runtime.gnss.gnss_ekf import filter_rows
    from tests.test_spp_bad_input import _solve

    obs, nf = _mutated_0759({})
    spp = _solve(obs, nf)
    idx = filter_rows(spp)
    assert "unfit_for_filter" not in spp.counts
    spp.rows.pseudorange_m[idx[5]] = -1.0         # as after a bad correction
    spp.rows.aux[idx[9], 0] = np.nan
    epoch_utc = gtime.gps_seconds_to_utc(float(spp.t_gps_s[0]) - 1.0).replace(tzinfo=dt.timezone.utc)
    table = coupled.observation_table(spp, epoch_utc).check()
    assert len(table) == idx.size - 2 and spp.counts["unfit_for_filter"] == 2


def test_a_clock_jump_inside_a_gap_is_given_to_the_next_solved_epoch_only():
    """Unsolved epochs in a gap keep the accumulated jump of the solved epoch before them (the
    docstring's rule); before they took the next solved epoch's jump."""
    import dataclasses

    from leonav_runtime.gen import constants as K
    from leonav_runtime.gnss import gnss_ekf
    from leonav_runtime.gnss import spp as _spp

    E = 12
    t = 1e9 + np.arange(E, dtype=float)
    ms = K.C_LIGHT_MPS * 1e-3
    clock = 150.0 + 0.3 * (t - t[0]) + ms * (np.arange(E) >= 6)    # drift 0.3 m/s, +1 ms from epoch 6
    status = np.full(E, _spp.SOLVED, np.int8)
    status[3:7] = _spp.TOO_FEW                                     # the step happens inside this gap
    fake = dataclasses.make_dataclass("S", ["t_gps_s", "clock_m", "status", "solved"])(
        t, clock, status, (status == _spp.SOLVED))
    jumps = gnss_ekf.clock_jumps_m(fake)
    assert np.array_equal(jumps, ms * (np.arange(E) >= 7))


def test_inter_system_bias_starts_from_the_nearest_epoch_where_it_is_finite():
    """Galileo absent at the start epoch, seen from the third: its bias starts at the third
    epoch's value, not 0; BeiDou never seen: 0."""
    from leonav_runtime.gen import state_layout as L
    from leonav_runtime.inputs import GnssObservationTable
    from leonav_runtime.inputs.gnss_obs import apply_clock_start
    from leonav_runtime.core.params import params_array

    isb = np.array([[np.nan, np.nan], [np.nan, np.nan], [12.5, np.nan], [13.0, np.nan], [np.nan, np.nan]])
    table = GnssObservationTable(np.zeros(0), np.zeros(0, int), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0),
                                 np.zeros((0, L.NAUX)), clock_t=np.arange(5.0), clock_m=np.full(5, 100.0), isb_m=isb)
    x0 = np.zeros(L.NX)
    x0[L.X_Q_NB] = 1.0
    for t_start, want in ((0.2, 12.5), (3.4, 13.0), (4.9, 13.0)):
        x, _, _, _ = apply_clock_start(x0, np.eye(L.NDX), params_array(0.6, 2.4, 50.0), table, t_start, L)
        assert list(x[L.X_ISB_SLICE]) == [want, 0.0]


def _leap_invalid_session(folder):
    """0759, first minute (2 epochs: the 60-s tag is 60.001 s), RAWX with leapS not valid (and
    wrong), no NMEA; returns (nav, number of epochs)."""
    from leonav_runtime.gnss.signals import primary_rows
    from tests.gnss_session import write_rawx_session
    from tests.test_gnss_coupled import geonet, nav_funcs

    obs, eph, klob = geonet("0759")
    rows, _ = primary_rows(obs, "G")
    o = obs.take(rows)
    o = o.take(np.flatnonzero((o.t_gps_s <= o.t_gps_s[0] + 60.0) & (o.signal == "1C") & np.isfinite(o.pseudorange_m)))
    write_rawx_session(folder, o.t_gps_s, o.prn, o.pseudorange_m, o.doppler_hz, o.cn0_dbhz, eph.data,
                       obs.approx_position_ecef_m, klobuchar=klob, nav=nav_funcs(), leap_valid=False)
    return nav_funcs(), np.unique(o.t_gps_s).size


def test_replay_of_rawx_without_valid_leap_seconds_uses_its_gps_time(tmp_path, monkeypatch):
    """No NMEA, RAWX leapS not valid: the IMU axis comes from the RAWX time map (not the host
    clock) and the pseudorange mode runs; with no time map at all it is skipped, with why."""
    from leonav.hardware import session_decode
    from leonav_runtime import replay

    nav, n_epochs = _leap_invalid_session(tmp_path / "s")
    options = replay.ReplayOptions(modes=("pseudorange+imu",), use_truth=False)
    inputs = replay.decode_inputs(tmp_path / "s", options, nav=nav)
    # (the first RAWX waits behind the SFRBX burst on the wire: an outlier of the fit)
    assert inputs.init["time_axis"].startswith("GNSS time map from RAWX ("), inputs.init["time_axis"]
    assert inputs.skipped == {} and inputs.counts["gnss_decoder"]["accepted"]["rawx_leap_from_table"] == n_epochs
    assert inputs.counts["gnss_pseudorange_records"] > 0
    monkeypatch.setattr(session_decode, "fit_time_map", lambda tags: TimeMap())
    inputs = replay.decode_inputs(tmp_path / "s", options, nav=nav)
    assert "host wall clock" in inputs.init["time_axis"]
    assert "no GNSS time tag" in inputs.skipped["pseudorange+imu"], inputs.skipped
