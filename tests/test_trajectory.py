"""Intended motion: speeds, headings and positions follow the manoeuvre segments."""
from __future__ import annotations

import math

import numpy as np
import pytest

from leonav_runtime.scenarios.load import load_scenario
from leonav_runtime.simulation.trajectory import motion


def test_static_profile_keeps_site_and_attitude():
    scn = load_scenario("paper")
    m = motion(scn, np.arange(0, 20.01, 0.01))
    assert np.all(m.p_enu_m == 0) and np.all(m.v_enu_mps == 0)
    assert np.allclose(m.rpy_rad, [0, 0, math.pi / 2])


def test_maritime_segments_give_expected_speed_heading_and_distance():
    scn = load_scenario("maritime-outage")
    t = np.arange(0, scn.duration_s + 1e-9, 0.01)
    m = motion(scn, t)
    speed = np.linalg.norm(m.v_enu_mps, axis=1)
    # first 60 s straight North at 8 m/s: 480 m North, no East motion
    i60 = np.searchsorted(t, 60.0)
    assert m.p_enu_m[i60] == pytest.approx([0.0, 480.0, 0.0], abs=1e-6)
    # after the 3 deg/s, 30 s turn the heading is 180 deg (West), speed unchanged
    i90 = np.searchsorted(t, 90.0)
    assert m.rpy_rad[i90, 2] == pytest.approx(math.pi)
    assert speed[i90] == pytest.approx(8.0)
    # a constant-speed 90 deg turn of radius v/omega moves r East-West and r North
    r = 8.0 / math.radians(3.0)
    assert m.p_enu_m[i90] - m.p_enu_m[i60] == pytest.approx([-r, r, 0.0], abs=1e-3)
    assert speed[np.searchsorted(t, 150.0)] == pytest.approx(11.0)
    # the position is the integral of the velocity (checked with an independent rule)
    p_check = np.cumsum(np.r_[[np.zeros(3)], 0.5 * (m.v_enu_mps[1:] + m.v_enu_mps[:-1]) * 0.01], 0)
    assert np.max(np.abs(p_check - m.p_enu_m)) < 0.01
    assert np.max(np.abs(m.rpy_rad[:, 0])) == pytest.approx(math.radians(3.0), rel=1e-3)
