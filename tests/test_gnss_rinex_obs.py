"""RINEX observation reader: GEONET RINEX 2.10 files (counts, values against georinex,
event flags), RINEX 3 text, bad input and seeded mutations."""
from __future__ import annotations

import random
import warnings

import numpy as np
import pytest

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gnss import time as gtime
from leonav_runtime.gnss.observations import (FLAG_HALF_CYCLE, FLAG_LOSS_OF_LOCK, FLAG_POWER_FAILURE,
                                              FLAG_PR_VALID, ObservationTable)
from leonav_runtime.gnss.rinex_obs import RejectedObservationsWarning, parse_rinex_obs, read_rinex_obs
from tests import gnss_rinex3_synth as synth
from tests.conftest import shared_file


def _text(station="0759"):
    return shared_file(f"gnss_rinex/{station}0920.05o").read_text()


@pytest.mark.parametrize("station,l1,l2,events", [("0759", 948, 924, 3), ("3040", 1039, 1036, 1)])
def test_geonet_counts(station, l1, l2, events):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        obs = read_rinex_obs(shared_file(f"gnss_rinex/{station}0920.05o"))
    assert isinstance(obs, ObservationTable)
    assert obs.epochs().size == 120 and obs.counts["epochs"] == 120
    assert (obs.signal == "1C").sum() == l1 and (obs.signal == "2W").sum() == l2
    assert obs.counts["event_flag_4"] == events and not obs.rejected
    assert obs.epochs()[0] == gtime.calendar_to_seconds(2005, 4, 2, 0, 0, 0.0)
    assert np.all(obs.has_flag(FLAG_PR_VALID))
    if station == "0759":
        np.testing.assert_allclose(obs.approx_position_ecef_m, [-3976219.5082, 3382372.5671, 3652512.9849])
        first = obs.take(slice(0, 2))
        assert list(first.prn) == [3, 3] and list(first.signal) == ["1C", "2W"]
        assert first.pseudorange_m[0] == 24767686.375 and first.carrier_phase_cyc[0] == 55923622.160
        assert first.pseudorange_m[1] == 24767684.822 and first.carrier_phase_cyc[1] == 43647388.242
        assert first.lli[1] == 4  # "43647388.2424": LLI 4 (anti-spoofing) on L2


def test_values_agree_with_georinex():
    gr = pytest.importorskip("georinex")
    path = shared_file("gnss_rinex/07590920.05o")
    obs = read_rinex_obs(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = gr.load(path)
    tt = (ds.time.values - np.datetime64("1980-01-06")).astype("timedelta64[ns]").astype(np.int64) * 1e-9
    sv = [str(s) for s in ds.sv.values]
    for code, sig, col in (("C1", "1C", "pseudorange_m"), ("L1", "1C", "carrier_phase_cyc"),
                           ("P2", "2W", "pseudorange_m"), ("L2", "2W", "carrier_phase_cyc")):
        arr = ds[code].values
        mine = obs.take(obs.signal == sig)
        i = np.abs(tt[None, :] - mine.t_gps_s[:, None]).argmin(axis=1)
        j = np.array([sv.index(f"G{p:02d}") for p in mine.prn])
        theirs = arr[i, j]
        ours = getattr(mine, col)
        assert np.array_equal(np.isnan(theirs), np.isnan(ours))
        assert np.array_equal(theirs[~np.isnan(theirs)], ours[~np.isnan(ours)])
        assert np.isfinite(arr).sum() == np.isfinite(ours).sum()


def test_rinex3_text():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        obs = parse_rinex_obs(synth.obs_text(), "t.obs")
    assert len(obs) == 15 and obs.epochs().size == 3
    c = obs.take((obs.system == "C") & (obs.prn == 1))
    assert list(c.signal) == ["2I"] * 3 and c.pseudorange_m[0] == 37912345.678 and c.doppler_hz[0] == -1234.567
    assert obs.t_gps_s[0] == gtime.calendar_to_seconds(2020, 6, 2, 1, 30, 0.0)


def test_bdt_and_glonass_time_systems():
    bdt = synth.obs_text().replace("    GPS         TIME OF FIRST OBS", "    BDT         TIME OF FIRST OBS")
    glo = synth.obs_text().replace("    GPS         TIME OF FIRST OBS", "    GLO         TIME OF FIRST OBS")
    t0 = gtime.calendar_to_seconds(2020, 6, 2, 1, 30, 0.0)
    assert parse_rinex_obs(bdt, "b").t_gps_s[0] == t0 + 14.0
    assert parse_rinex_obs(glo, "g").t_gps_s[0] == t0 + 18.0


def test_flags_power_failure_lli_and_zero_values():
    lines = _text().splitlines()
    # first epoch line is line 18 (1-based): flag 1; first satellite's L1 gets LLI 1, its C1 becomes 0
    lines[17] = lines[17][:28] + "1" + lines[17][29:]
    lines[18] = "  55923622.1601" + lines[18][15:]
    lines[18] = lines[18][:16] + "         0.000 " + lines[18][32:]
    obs = parse_rinex_obs("\n".join(lines), "f")
    first = obs.take(obs.t_gps_s == obs.t_gps_s[0])
    assert np.all(first.has_flag(FLAG_POWER_FAILURE))
    g3 = first.take((first.prn == 3) & (first.signal == "1C"))
    assert np.isnan(g3.pseudorange_m[0]) and g3.has_flag(FLAG_LOSS_OF_LOCK)[0]
    assert obs.counts["zero_C"] == 1
    assert not obs.take(obs.signal == "2W").has_flag(FLAG_HALF_CYCLE).any()


def test_bad_input_names_line_and_field():
    lines = _text().splitlines()
    lines[19] = lines[19][:18] + "x" + lines[19][19:]       # line 20: garble the C1 of G07
    lines[26] = "garbage garbage"                             # line 27: break the 2nd epoch line
    with pytest.warns(RejectedObservationsWarning):
        obs = parse_rinex_obs("\n".join(lines), "f.o")
    first, second = obs.rejected[0], obs.rejected[1]
    assert (first.line, first.field) == (20, "C1 of G07") and "not a number" in first.reason
    assert (second.line, second.field) == (27, "epoch")
    assert obs.epochs().size == 119  # the broken epoch is dropped, the rest is read
    clean = parse_rinex_obs(_text(), "f.o")
    g07 = obs.take((obs.t_gps_s == obs.t_gps_s[0]) & (obs.prn == 7) & (obs.signal == "1C"))
    assert np.isnan(g07.pseudorange_m[0]) and g07.carrier_phase_cyc[0] == -691177.898
    assert len(obs) == len(clean) - 16
    with pytest.raises(UserInputError, match=r"f:1: field RINEX VERSION: version 1"):
        parse_rinex_obs(_text().replace("     2.10", "     1.00", 1), "f")
    with pytest.raises(UserInputError, match="expected 'O'"):
        parse_rinex_obs(shared_file("gnss_rinex/07590920.05n").read_text(), "f")


def test_truncated_file_keeps_complete_satellites():
    lines = _text().splitlines()
    cut = lines[: 17 + 9 + 3]  # header, first epoch, second epoch with G03 and a cut G07 line
    with pytest.warns(RejectedObservationsWarning):
        obs = parse_rinex_obs("\n".join(cut[:-1] + [cut[-1][:20]]), "t.o")
    assert obs.epochs().size == 2
    second = obs.take(obs.t_gps_s == obs.epochs()[1])
    assert list(second.prn) == [3, 3, 7]
    assert second.carrier_phase_cyc[2] == -701908.445 and np.isnan(second.pseudorange_m[2])
    cut_field, missing = obs.rejected
    assert (cut_field.line, cut_field.field) == (29, "C1 of G07") and "cut short" in cut_field.reason
    assert (missing.line, missing.field) == (30, "observations of G08")


@pytest.mark.parametrize("seed", range(30))
def test_seeded_mutations(seed):
    """One random line mutation: epochs other than the touched one come back unchanged."""
    text = _text()
    clean = parse_rinex_obs(text, "f")
    lines = text.splitlines()
    rng = random.Random(1000 + seed)
    k = rng.randrange(17, len(lines))
    kind = rng.choice(["char", "delete", "truncate", "garbage", "duplicate"])
    if kind == "char" and lines[k]:
        j = rng.randrange(len(lines[k]))
        lines[k] = lines[k][:j] + rng.choice("x?-. 9e") + lines[k][j + 1:]
    elif kind == "delete":
        del lines[k]
    elif kind == "truncate":
        lines[k] = lines[k][: rng.randrange(len(lines[k]) + 1)]
    elif kind == "duplicate":
        lines.insert(k, lines[k])
    else:
        lines[k] = "".join(rng.choice("ab01 .-") for _ in range(rng.randrange(1, 80)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        obs = parse_rinex_obs("\n".join(lines), "f")
    # epochs are 30 s apart: the mutated line lies in at most two of them
    changed = []
    for t in clean.epochs():
        a = clean.take(clean.t_gps_s == t).to_structured()
        b = obs.take(obs.t_gps_s == t).to_structured()
        if a.tobytes() != b.tobytes():
            changed.append(t)
    assert len(changed) <= 2, (kind, k, changed)
    for rej in obs.rejected:
        assert rej.source == "f" and rej.line > 0


def test_an_epoch_of_no_satellite_is_read_not_looped_on():
    """A RINEX 2 epoch line announcing 0 satellites (a receiver that lost every signal) ends at its
    line: the reader goes on with the next epoch (it looped forever on it before)."""
    lines = _text().splitlines()
    empty = lines[17][:29] + "  0"     # the first epoch's line, its satellite count set to 0, no list
    obs = parse_rinex_obs("\n".join(lines[:17] + [empty] + lines[17:]), "f.o")
    clean = parse_rinex_obs(_text(), "f.o")
    assert len(obs) == len(clean) and obs.epochs().size == clean.epochs().size
