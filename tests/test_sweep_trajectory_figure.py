"""trajectories.png marks what a reader needs: a static truth as one visible point, and where each
mode's estimate starts (the initial error, tens of metres, is otherwise a line from nowhere)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from leonav_runtime.sweep import plots


def _figure(monkeypatch, truth: np.ndarray, trajectories: dict[str, np.ndarray]):
    saved = {}
    monkeypatch.setattr(plots.ps, "save", lambda fig, path: saved.setdefault("fig", fig))
    scn = SimpleNamespace(modes=list(trajectories), gps={"outages": []}, name="t", starlink={"counts": [5]})
    res = SimpleNamespace(truth_p_enu=truth, t_eval=np.arange(truth.shape[0], dtype=float),
                          trajectories=trajectories)
    plots.plot_trajectories(scn, res, "unused.png")
    plan = saved["fig"].axes[0]
    return plan, [t.get_text() for t in saved["fig"].legends[0].get_texts()]


def _markers(ax, marker: str) -> list[tuple[float, float]]:
    return [(float(l.get_xdata()[0]), float(l.get_ydata()[0])) for l in ax.lines if l.get_marker() == marker]


def test_static_truth_is_one_marker_on_top_and_each_estimate_start_is_marked(monkeypatch):
    truth = np.zeros((50, 3))
    est = {"gps+imu": np.column_stack([np.linspace(-8, 0, 50), np.linspace(26, 0, 50), np.zeros(50)]),
           "leo-alpha+imu": np.column_stack([np.linspace(2, 0, 50), np.zeros(50), np.zeros(50)])}
    plan, labels = _figure(monkeypatch, truth, est)
    stars = [l for l in plan.lines if l.get_marker() == "*"]
    assert len(stars) == 1 and stars[0].get_zorder() > max(l.get_zorder() for l in plan.lines if l is not stars[0])
    assert not _markers(plan, "^") and not _markers(plan, "s")  # no start/end pair hiding each other
    assert sorted(_markers(plan, "o")) == sorted([(-8.0, 26.0), (2.0, 0.0)])
    assert "truth (static)" in labels and "first estimate of each mode" in labels


def test_moving_truth_keeps_start_above_end(monkeypatch):
    truth = np.column_stack([np.linspace(0, 300, 50), np.zeros(50), np.zeros(50)])
    plan, labels = _figure(monkeypatch, truth, {"gps+imu": truth + 1.0})
    (start,), (end,) = _markers(plan, "^"), _markers(plan, "s")
    assert start == pytest.approx((0.0, 0.0)) and end == pytest.approx((300.0, 0.0))
    z = {l.get_marker(): l.get_zorder() for l in plan.lines}
    assert z["^"] > z["s"]
    assert {"truth", "start", "end"} <= set(labels)
