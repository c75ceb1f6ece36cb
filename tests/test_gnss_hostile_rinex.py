"""Hostile RINEX observation files (issue 24, failures 4, 5 and 8).

* 4: epochs out of time order (one swapped pair) and a repeated epoch made `leonav spp` stop
  with `LinAlgError: Singular matrix`; they are sorted / dropped and counted, and the
  solutions equal those of the untouched file (and rnx2rtkp's on the same edited file).
* 5: RINEX 3, a blank line inside a satellite block and an epoch line cut before column 32
  raised IndexError; each is a rejection naming file, line and what was expected.
* 8: `leonav spp --ekf` with no single-point solution raised ValueError (exit 1); it is one
  line saying so, exit 2.

The bad files are edited copies, written to tmp_path, of the shared GEONET 0759 file (RINEX
2.10) or of the synthetic RINEX 3.03 text of tests/gnss_rinex3_synth.py.
"""
from __future__ import annotations

import csv
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from leonav_runtime.cli import main
from leonav_runtime.gnss.rinex_obs import parse_rinex_obs
from leonav_runtime.gnss.rinex_obs_v2 import V2_EPOCH
from tests import gnss_rinex3_synth as synth
from tests.conftest import shared_file

RNX2RTKP = shutil.which("rnx2rtkp")
needs_rtklib = pytest.mark.skipif(RNX2RTKP is None, reason="rnx2rtkp (Debian package rtklib) not installed")
pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")   # the reader warns of its rejections


# ------------------------------------------------------------------ helpers

def _v2_blocks(text: str) -> tuple[list[str], list[list[str]]]:
    """(header lines, epoch blocks: epoch line + its satellite lines) of a RINEX 2 file."""
    lines = text.splitlines()
    k = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    blocks: list[list[str]] = []
    for ln in lines[k:]:
        if V2_EPOCH.match(ln):
            blocks.append([ln])
        else:
            blocks[-1].append(ln)
    return lines[:k], blocks


def _write(path: Path, header: list[str], blocks: list[list[str]]) -> Path:
    path.write_text("\n".join(header + [ln for b in blocks for ln in b]) + "\n")
    return path


def _spp(obs: Path, nav: Path, out: Path, *extra: str) -> tuple[int, dict | None]:
    rc = main(["spp", str(obs), "--nav", str(nav), "--out", str(out), *extra])
    js = out / "spp.json"
    return rc, (json.loads(js.read_text())["files"][0] if js.exists() else None)


def _positions(csv_path: Path) -> dict[float, np.ndarray]:
    """{t_gps_s: ECEF (m)} of the solved epochs of a `leonav spp` <name>.csv."""
    with csv_path.open() as fh:
        return {float(r["t_gps_s"]): np.array([float(r["x_ecef_m"]), float(r["y_ecef_m"]), float(r["z_ecef_m"])])
                for r in csv.DictReader(fh) if r["status"].startswith("ok")}


def _rtklib_pos(obs: Path, nav: Path, out: Path) -> Path:
    subprocess.run([RNX2RTKP, "-p", "0", "-m", "10", "-sys", "G", "-o", str(out), str(obs), str(nav)],
                   check=True, capture_output=True, timeout=120)
    return out


ATMOSPHERE_OFF = ("--iono", "off", "--tropo", "off")   # rnx2rtkp -p 0's defaults


# ------------------------------------------------------------------ 4: epoch order

def test_swapped_epoch_pair_is_sorted_counted_and_solves_as_the_original(tmp_path, capsys):
    o, n = shared_file("gnss_rinex/07590920.05o"), shared_file("gnss_rinex/07590920.05n")
    header, blocks = _v2_blocks(o.read_text())
    assert len(blocks) == 120
    blocks[10], blocks[11] = blocks[11], blocks[10]
    bad = _write(tmp_path / "swapped.05o", header, blocks)

    rc, s = _spp(bad, n, tmp_path / "bad", *ATMOSPHERE_OFF)
    printed = capsys.readouterr().out
    assert rc == 0
    assert s["epochs"] == 120 and s["epochs_solved"] == 120
    assert s["reader_counts"]["epochs_out_of_order"] == 1
    assert "1 epoch out of time order (sorted)" in printed
    rc, ref = _spp(o, n, tmp_path / "good", *ATMOSPHERE_OFF)
    assert rc == 0 and "epochs_out_of_order" not in ref["reader_counts"]
    ours, theirs = _positions(tmp_path / "bad" / "swapped_05o.csv"), _positions(tmp_path / "good" / "07590920_05o.csv")
    assert ours.keys() == theirs.keys()
    assert max(np.linalg.norm(ours[t] - theirs[t]) for t in ours) < 1e-4   # the same solutions, 0.1 mm printed


@needs_rtklib
def test_swapped_epoch_pair_matches_rnx2rtkp_on_the_same_file(tmp_path):
    o, n = shared_file("gnss_rinex/07590920.05o"), shared_file("gnss_rinex/07590920.05n")
    header, blocks = _v2_blocks(o.read_text())
    blocks[10], blocks[11] = blocks[11], blocks[10]
    bad = _write(tmp_path / "swapped.05o", header, blocks)
    ref = _rtklib_pos(bad, n, tmp_path / "rtklib.pos")
    rc, s = _spp(bad, n, tmp_path / "out", *ATMOSPHERE_OFF, "--compare", str(ref))
    assert rc == 0
    c = s["compare"][str(ref)]
    assert c["epochs_matched"] == 120
    assert c["max_3d_m"] < 0.005 and c["same_ns"] == 120


def test_repeated_epoch_is_rejected_by_line_and_counted(tmp_path, capsys):
    o, n = shared_file("gnss_rinex/07590920.05o"), shared_file("gnss_rinex/07590920.05n")
    header, blocks = _v2_blocks(o.read_text())
    blocks.insert(11, list(blocks[10]))   # epoch 11 written twice, one after the other
    blocks.insert(30, list(blocks[20]))   # and epoch 21 again later, out of order as well
    bad = _write(tmp_path / "repeated.05o", header, blocks)
    first_copy_line = len(header) + sum(len(b) for b in blocks[:11]) + 1

    rc, s = _spp(bad, n, tmp_path / "bad", *ATMOSPHERE_OFF)
    printed = capsys.readouterr().out
    assert rc == 0
    assert s["epochs"] == 120 and s["epochs_solved"] == 120
    assert s["reader_counts"]["duplicate_epochs"] == 2
    assert "2 repeated epochs (dropped)" in printed
    assert any(r.startswith(f"{bad}:{first_copy_line}: epoch: ") and "repeats the epoch of line" in r
               for r in s["reader_rejections"]), s["reader_rejections"]
    assert _spp(o, n, tmp_path / "good", *ATMOSPHERE_OFF)[0] == 0
    ours, theirs = _positions(tmp_path / "bad" / "repeated_05o.csv"), _positions(tmp_path / "good" / "07590920_05o.csv")
    assert ours.keys() == theirs.keys()
    assert max(np.linalg.norm(ours[t] - theirs[t]) for t in ours) < 1e-4


def test_reader_keeps_rows_in_time_order():
    o = shared_file("gnss_rinex/07590920.05o")
    header, blocks = _v2_blocks(o.read_text())
    blocks = blocks[::-1]   # the whole file backwards
    obs = parse_rinex_obs("\n".join(header + [ln for b in blocks for ln in b]) + "\n", "reversed.05o")
    assert obs.counts["epochs_out_of_order"] == 119
    assert np.all(np.diff(obs.t_gps_s) >= 0)
    good = parse_rinex_obs(o.read_text(), "07590920.05o")
    assert len(obs) == len(good) and np.array_equal(np.unique(obs.t_gps_s), np.unique(good.t_gps_s))


def test_single_point_solve_accepts_rows_out_of_time_order():
    """A table not from the RINEX reader (e.g. merged logs) may be out of time order: the
    solver groups its rows by epoch itself."""
    from leonav_runtime.gnss import spp
    from leonav_runtime.gnss.rinex_nav import read_rinex_nav
    from leonav_runtime.gnss.signals import gnss_rows, klobuchar_coefficients
    from tests.test_spp import nav_funcs

    obs = parse_rinex_obs(shared_file("gnss_rinex/07590920.05o").read_text(), "07590920.05o")
    nf = read_rinex_nav(shared_file("gnss_rinex/07590920.05n"))
    epochs = np.unique(obs.t_gps_s)
    order = np.concatenate([np.flatnonzero(obs.t_gps_s == t) for t in epochs[np.r_[11, 10, 12:120, 0:10]]])

    def solve(table):
        rows = gnss_rows(table, nf.ephemerides, klobuchar=klobuchar_coefficients(nf.iono), systems="G")
        return spp.solve(rows, spp.SppOptions(elevation_mask_deg=10.0),
                         approx_ecef_m=table.approx_position_ecef_m, nav=nav_funcs())

    good, shuffled = solve(obs), solve(obs.take(order))
    assert np.array_equal(good.t_gps_s, shuffled.t_gps_s) and shuffled.solved.all()
    assert np.abs(good.r_ecef_m - shuffled.r_ecef_m).max() < 1e-6
    assert np.array_equal(good.ns, shuffled.ns)


# ------------------------------------------------------------------ 5: RINEX 3 cut records

def _v3_lines() -> tuple[list[str], int]:
    lines = synth.obs_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if "END OF HEADER" in ln) + 1
    return lines, k   # lines[k] is epoch 1, lines[k + 6] epoch 2 (5 satellites each)


def test_rinex3_blank_line_inside_a_satellite_block_is_a_rejection(tmp_path, capsys):
    lines, k = _v3_lines()
    second = k + 6
    lines.insert(second + 2, "")   # after the first two satellites of epoch 2
    path = tmp_path / "blank.rnx"
    path.write_text("\n".join(lines) + "\n")
    obs = parse_rinex_obs(path.read_text(), str(path))
    assert [(r.line, r.field) for r in obs.rejected] == [(second + 3, "satellite line")]
    assert "blank line" in obs.rejected[0].reason and f"epoch of line {second + 1}" in obs.rejected[0].reason
    assert obs.counts["epochs"] == 3
    assert len(obs) == 3 * len(synth.OBS_SATS)   # the satellites after the blank line are still read
    assert main(["gnss", "obs", str(path)]) == 0
    assert f"{path}:{second + 3}: satellite line: blank line" in capsys.readouterr().out


@pytest.mark.parametrize("cut", (31, 20, 3))
def test_rinex3_epoch_line_cut_before_column_32_is_a_rejection(tmp_path, capsys, cut):
    lines, k = _v3_lines()
    second = k + 6
    lines[second] = lines[second][:cut]
    path = tmp_path / "cut.rnx"
    path.write_text("\n".join(lines) + "\n")
    obs = parse_rinex_obs(path.read_text(), str(path))
    assert [(r.line, r.field) for r in obs.rejected] == [(second + 1, "epoch")]
    assert f"cut at column {cut}" in obs.rejected[0].reason and "epoch flag in column 32" in obs.rejected[0].reason
    assert obs.counts["epochs"] == 2 and len(obs) == 2 * len(synth.OBS_SATS)   # its satellite lines skipped
    assert main(["gnss", "obs", str(path)]) == 0
    assert f"{path}:{second + 1}: epoch: " in capsys.readouterr().out


# ------------------------------------------------------------------ 8: --ekf without a solution

def test_ekf_without_any_single_point_solution_is_one_line_exit_2(tmp_path, capsys):
    """Only 3 satellites in every epoch: no epoch can be solved, the EKF has no start."""
    o, n = shared_file("gnss_rinex/07590920.05o"), shared_file("gnss_rinex/07590920.05n")
    header, blocks = _v2_blocks(o.read_text())
    for b in blocks:   # keep the first 3 satellites (one 4-type line each) of every epoch
        sats = b[0][32:68]
        b[0] = b[0][:29] + f"{3:3d}" + sats[:9]
        del b[4:]
    bad = _write(tmp_path / "three_sats.05o", header, blocks)
    rc = main(["spp", str(bad), "--nav", str(n), "--ekf", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert len(err) == 1, err
    assert err[0].startswith(f"leonav spp: error: {bad}: --ekf: no epoch has a single-point solution")
    assert "too_few_satellites 120" in err[0]
    assert "Traceback" not in err[0]


def test_ekf_when_the_mask_leaves_no_solution_names_the_reason(tmp_path, capsys):
    o, n = shared_file("gnss_rinex/07590920.05o"), shared_file("gnss_rinex/07590920.05n")
    rc = main(["spp", str(o), "--nav", str(n), "--ekf", "--elevation-mask", "89", "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert "no epoch has a single-point solution" in err[0] and "below_elevation_mask" in err[0]
