"""Bad input to `leonav spp`: counted rejections, one-line errors naming file/line/field."""
from __future__ import annotations

import json

import numpy as np
import pytest

from leonav_runtime.cli import main
from leonav_runtime.gnss import spp
from leonav_runtime.gnss.rinex_nav import parse_rinex_nav, read_rinex_nav
from leonav_runtime.gnss.rinex_obs import parse_rinex_obs
from leonav_runtime.gnss.signals import gnss_rows, klobuchar_coefficients
from tests.conftest import shared_file
from tests.test_spp import nav_funcs


def _texts():
    obs = shared_file("gnss_rinex/07590920.05o").read_text()
    nav = shared_file("gnss_rinex/07590920.05n").read_text()
    return obs, nav


def _first_epoch_lines(obs_text: str) -> tuple[list[str], int]:
    lines = obs_text.splitlines()
    k = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    return lines, k  # lines[k] is the first epoch line; lines[k+1] the first satellite (G03)


def _solve(obs, nf, **kw):
    rows = gnss_rows(obs, nf.ephemerides, klobuchar=klobuchar_coefficients(nf.iono), systems="G", **kw)
    return spp.solve(rows, spp.SppOptions(elevation_mask_deg=10.0), approx_ecef_m=obs.approx_position_ecef_m,
                     nav=nav_funcs())


def test_zero_and_blank_pseudoranges_are_counted_not_used():
    obs_text, nav_text = _texts()
    lines, k = _first_epoch_lines(obs_text)
    # satellite 2 of epoch 1 (G07): C1 (columns 17-30) zero; satellite 3 (G08): C1 blank
    lines[k + 2] = lines[k + 2][:16] + "         0.000" + lines[k + 2][30:]
    lines[k + 3] = lines[k + 3][:16] + " " * 14 + lines[k + 3][30:]
    obs = parse_rinex_obs("\n".join(lines) + "\n", "mutated.05o")
    assert obs.counts["zero_C"] == 1
    res = _solve(obs, parse_rinex_nav(nav_text, "07590920.05n"))
    assert res.counts["no_pseudorange"] == 2
    assert res.solved.all() and res.ns[0] == 5  # 7 above the mask, 2 without a pseudorange


def test_satellites_without_nav_unhealthy_or_stale_are_counted():
    obs_text, nav_text = _texts()
    obs = parse_rinex_obs(obs_text, "07590920.05o")
    nf = parse_rinex_nav(nav_text, "07590920.05n")
    d = nf.ephemerides.data
    keep = d["prn"] != 28  # G28: no ephemeris at all
    d["health"][d["prn"] == 24] = 1  # G24: only unhealthy records
    d["toe"][d["prn"] == 20] += 86400.0  # G20: nearest toe a day away (stale)
    nf.ephemerides = nf.ephemerides.take(np.flatnonzero(keep))
    res = _solve(obs, nf)
    n_epochs = {p: len(np.unique(obs.t_gps_s[(obs.prn == p) & (obs.signal == "1C")])) for p in (28, 24, 20)}
    assert res.counts["no_ephemeris"] == n_epochs[28]
    assert res.counts["unhealthy"] == n_epochs[24]
    assert res.counts["stale_ephemeris"] == n_epochs[20]
    # 4 satellites left above 10 deg for the first half hour, 3 after G08 sets
    assert res.solved.sum() + res.counts["epochs_too_few_satellites"] == 120 and res.solved.sum() >= 60
    assert not any(s in ("G20", "G24", "G28") for e in range(res.t_gps_s.size) for s in res.used_sats(e))


def test_cli_errors_are_one_line_and_name_the_file(tmp_path, capsys):
    obs = shared_file("gnss_rinex/07590920.05o")
    nav = shared_file("gnss_rinex/07590920.05n")
    cases = [
        (["spp", str(tmp_path / "missing.05o"), "--nav", str(nav)], "missing.05o: observation file not found"),
        (["spp", str(obs)], "needs --nav NAV"),
        (["spp", str(obs), "--nav", str(obs)], "07590920.05o:1: field FILE TYPE"),
        (["spp", str(obs), "--nav", str(nav), "--elevation-mask", "95"], "--elevation-mask 95.0: expected degrees"),
        (["spp", str(obs), "--nav", str(nav), "--systems", "GX"], "--systems 'GX'"),
        (["spp", str(obs), "--nav", str(nav), "--compare", "a.pos", "b.pos"], "--compare: 2 reference file(s) for 1"),
    ]
    for argv, expected in cases:
        rc = main(argv + ["--out", str(tmp_path / "o")])
        err = capsys.readouterr().err.strip()
        assert rc == 2, argv
        assert len(err.splitlines()) == 1 and expected in err, (argv, err)


def test_unreadable_epoch_is_rejected_with_its_line_and_the_rest_solved(tmp_path, capsys):
    obs_text, _ = _texts()
    lines, k = _first_epoch_lines(obs_text)
    # the epoch line of the second epoch (after 8 satellite lines) replaced by garbage
    second = k + 1 + 8
    assert lines[second].startswith(" 05  4  2  0  0 30.0000000")
    lines[second] = " 05  4  2 xx  0 30.0000000  0  8G 3G 7G 8G11G19G20G24G28"
    bad = tmp_path / "bad0920.05o"
    bad.write_text("\n".join(lines) + "\n")
    rc = main(["spp", str(bad), "--nav", str(shared_file("gnss_rinex/07590920.05n")), "--out", str(tmp_path / "o")])
    assert rc == 0
    err = capsys.readouterr().err     # the CLI shows a warning as one line
    assert "leonav spp: warning: " in err and "1 observation lines/fields rejected" in err, err
    summary = json.loads((tmp_path / "o" / "spp.json").read_text())["files"][0]
    assert summary["epochs_solved"] == 119
    assert any(r.startswith(f"{bad}:{second + 1}:") for r in summary["reader_rejections"]), summary["reader_rejections"]
    capsys.readouterr()


def test_no_klobuchar_coefficients_is_counted_and_the_ionosphere_left_out():
    obs_text, nav_text = _texts()
    nav_text = "\n".join(ln for ln in nav_text.splitlines() if "ION ALPHA" not in ln and "ION BETA" not in ln)
    nf = parse_rinex_nav(nav_text + "\n", "noion.05n")
    assert klobuchar_coefficients(nf.iono) is None
    rows = gnss_rows(parse_rinex_obs(obs_text, "x"), nf.ephemerides, klobuchar=None, systems="G")
    assert rows.counts["no_klobuchar_coefficients"] == 1 and not rows.iono_on
    assert read_rinex_nav(shared_file("gnss_rinex/07590920.05n")).iono["GPSA"][0] == pytest.approx(1.118e-08)
