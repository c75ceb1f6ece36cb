"""Figures: plain log tick labels, one legend outside the panels, units in brackets, the
paper's bands on rmse_vs_count, and the result files' units (rmse.csv, findings.csv)."""
from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from leonav_runtime.common import plot_style
from leonav_runtime.sweep import plots as sweep_plots
from tests.conftest import short_paper_scenario
from leonav_runtime.sky.plot import short_label
from leonav_runtime.sweep.run import run_sweep


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    scn = short_paper_scenario(3.0, [5, 10], "<figures test>")
    out = tmp_path_factory.mktemp("tiny")
    return scn, run_sweep(scn, out, trials=2, workers=1, progress=False, figures=False), out


def _capture(monkeypatch):
    figs = []
    monkeypatch.setattr(plot_style, "save", lambda fig, path: figs.append(fig))
    return figs


def test_log_ticks_are_plain_numbers():
    plt = plot_style.pyplot()
    fig, ax = plt.subplots()
    ax.plot([1, 2, 3], [0.3, 6.0, 40.0])
    plot_style.plain_log_axis(ax)
    fig.canvas.draw()
    labels = [t.get_text() for t in ax.get_yticklabels() if t.get_text()]
    plt.close(fig)
    assert labels and all("10^" not in s and "times" not in s and "×" not in s for s in labels), labels
    assert "5" in labels and "0.5" in labels and "20" in labels


@pytest.mark.parametrize("name", ["plot_rmse_vs_count", "plot_rmse_vs_time", "plot_trajectories"])
def test_one_legend_outside_the_panels_and_units_in_brackets(tiny, monkeypatch, name):
    scn, res, _ = tiny
    figs = _capture(monkeypatch)
    getattr(sweep_plots, name)(scn, res, "unused.png")
    fig = figs[0]
    fig.canvas.draw()
    assert all(ax.get_legend() is None for ax in fig.axes)
    assert len(fig.legends) == 1
    box = fig.legends[0].get_window_extent()
    for ax in fig.axes:
        assert not box.overlaps(ax.get_window_extent()), name
        for label in (ax.get_xlabel(), ax.get_ylabel()):
            assert not label or ("[" in label and label.endswith("]")), label
    assert fig.get_figwidth() == pytest.approx(plot_style.COLUMN_WIDTH_IN)


def test_rmse_vs_count_shows_the_paper_bands_and_a_visible_bound(tiny, monkeypatch):
    scn, res, _ = tiny
    figs = _capture(monkeypatch)
    sweep_plots.plot_rmse_vs_count(scn, res, "unused.png")
    ax = figs[0].axes[0]
    spans = sorted((round(p.get_extents().y0), p) for p in ax.patches)
    ylims = [tuple(np.round(ax.transData.inverted().transform(p.get_extents())[:, 1], 3)) for _, p in spans]
    assert (1.0, 2.0) in ylims and (6.0, 9.0) in ylims, ylims
    # the sqrt(PCRB) series carries a marker, so it shows even with one count
    assert sum(1 for line in ax.lines if line.get_marker() == "_") == len(scn.modes)


def test_result_files_carry_units_and_both_rmse_kinds(tiny):
    scn, res, out = tiny
    with open(out / "rmse.csv") as fh:
        rows = list(csv.DictReader(fh))
    s = res.summaries[("gps+imu", 5)]
    row = next(r for r in rows if r["mode"] == "gps+imu" and r["count"] == "5")
    assert float(row["att_rmse_deg"]) == pytest.approx(math.degrees(s["attitude"]["rmse"]))
    assert float(row["pos_final_rmse_m"]) == pytest.approx(s["position"]["final_rmse"])
    metrics = json.loads((out / "metrics.json").read_text())
    pos = metrics["results"][0]["position"]
    assert "sqrt_pcrb" in pos and "pcrb" not in pos
    with open(out / "findings.csv") as fh:
        found = list(csv.DictReader(fh))
    band = [r for r in found if r["paper_low_m"]]
    assert band and all(float(r["position_rmse_final_m"]) > 0 and float(r["position_rmse_time_avg_m"]) > 0
                        for r in band)


def test_sky_labels_are_short():
    assert short_label("GPS BIIR-2  (PRN 13)", 24876) == "G13"
    assert short_label("STARLINK-31190", 58897) == "SL-31190"
    assert short_label("STARLINK-1008", 44714) == "SL-1008"   # not a bare 4-digit tail
    assert short_label("ONEWEB-0012", 44057) == "ONEWEB-0012"
    assert short_label("A VERY LONG SATELLITE NAME", 1234) == "#1234"


def test_waterfall_labels_each_satellite_once_and_predictions_lie_on_the_ridges(tmp_path, monkeypatch):
    from matplotlib.colors import to_rgba

    from leonav_runtime.cli import main
    from tests.conftest import shared_file

    tle = shared_file("tle/starlink_2026-02-23.txt")
    figs = _capture(monkeypatch)
    assert main(["-q", "beacons", str(tmp_path / "sim"), "--simulate", "--tle", str(tle), "--duration", "5",
                 "--sim-rate", "500e3", "--band", "500e3", "--n-sats", "2", "--tones", "3", "--cn0", "40",
                 "--start", "2026-02-23T06:00:00Z", "--out", str(tmp_path / "o")]) == 0
    fig = figs[-1]
    ax = fig.axes[0]
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    names = {a["name"] for a in summary["associations"] if a["status"] == "associated"}
    labels = [t.get_text() for t in ax.texts]
    assert len(names) == 2 and len(labels) == len(names) and all(any(n in s for s in labels) for n in names)
    assert any("[dB]" in a.get_ylabel() for a in fig.axes[1:])  # the colour bar
    white = to_rgba("white")
    predicted = [ln for ln in ax.lines if to_rgba(ln.get_color()) == white]
    ridges = [ln for ln in ax.lines if to_rgba(ln.get_color()) != white]
    assert len(predicted) == summary["counts"]["associated"] >= 4
    bin_khz = summary["stft"]["bin_hz"] / 1e3
    assert len(ridges) == summary["counts"]["ridges"]
    for i, p in enumerate(ax.lines):  # a prediction is drawn right after its ridge, at the ridge's times
        if to_rgba(p.get_color()) != white:
            continue
        ridge = ax.lines[i - 1]
        assert np.array_equal(ridge.get_ydata(), p.get_ydata())
        assert np.max(np.abs(np.asarray(p.get_xdata()) - np.asarray(ridge.get_xdata()))) < 3 * bin_khz
