"""Receiver clock: two-state (bias c_dt in m, drift c_ddt in m/s) random process.

Continuous model: d(c_dt)/dt = c_ddt + w1, d(c_ddt)/dt = w2 with white-noise PSDs
q_cdt (m^2/s, white frequency noise) and q_cddt (m^2/s^3, random-walk frequency noise).
From Allan-variance coefficients (Brown & Hwang, "Introduction to Random Signals and
Applied Kalman Filtering", two-state clock model): q_cdt = c^2 h0 / 2, q_cddt = c^2 2 pi^2 h_-2.
Pure arithmetic, so the functions work on floats and on casadi expressions.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from leonav.models.constants import C_LIGHT_MPS


@dataclass(frozen=True)
class ClockProfile:
    """Two-state receiver clock noise: white-frequency and random-walk-frequency PSDs (SI)."""

    name: str
    q_cdt: float    # m^2/s
    q_cddt: float   # m^2/s^3
    source: str


def from_allan(name: str, h0: float, h_m2: float, source: str) -> ClockProfile:
    """Clock PSDs from the h0 and h_-2 Allan coefficients (s and 1/s)."""
    return ClockProfile(name, C_LIGHT_MPS**2 * h0 / 2, C_LIGHT_MPS**2 * 2 * math.pi**2 * h_m2, source)


TCXO = from_allan("tcxo", 2e-19, 2e-20, "typical TCXO Allan coefficients h0=2e-19 s, h-2=2e-20 1/s (Brown & Hwang)")


def clock_qd(q_cdt, q_cddt, dt):
    """Exact discrete covariance of (c_dt, c_ddt) over dt: returns (q11, q12, q22)."""
    return q_cdt * dt + q_cddt * dt**3 / 3, q_cddt * dt**2 / 2, q_cddt * dt
