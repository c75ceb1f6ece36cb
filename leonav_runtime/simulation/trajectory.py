"""Reference motion of a scenario: where the vehicle is meant to go, in the local ENU frame.

This is the *intended* motion (a kinematic profile), not the navigation model: the
simulator turns it into IMU increments through the generated mechanization and takes the
truth from that same mechanization, so truth and filter share one model.

Profiles:
- ``static``: constant position (ENU origin) and attitude.
- ``maneuvers``: a surface vessel. Piecewise-constant longitudinal acceleration and turn
  rate (``[duration_s, acceleration_mps2, turn_rate_rad_s]`` segments) drive speed and
  heading; waves add sinusoidal roll and pitch. Heading is the yaw angle, counted from
  East towards North (ARCHITECTURE.md), and the velocity is along the heading.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.scenarios.load import Scenario

_FINE = 20  # sub-steps per output sample for the position integral (keeps it << 1 mm)


@dataclass
class Motion:
    """Intended motion sampled at `t_s` (s since the scenario epoch).

    `p_enu_m`, `v_enu_mps` (n, 3) in the ENU frame at the scenario site; `rpy_rad` (n, 3)
    roll, pitch, yaw of `C_b_n = Rz(yaw) Ry(pitch) Rx(roll)` (`euler_rad` is its old name).
    """

    t_s: np.ndarray
    p_enu_m: np.ndarray
    v_enu_mps: np.ndarray
    rpy_rad: np.ndarray

    @property
    def euler_rad(self) -> np.ndarray:
        return self.rpy_rad


def _speed_heading(t_s: np.ndarray, speed0: float, yaw0: float,
                   maneuvers: list[tuple[float, float, float]]) -> tuple[np.ndarray, np.ndarray]:
    """Speed (m/s) and heading (rad) at `t_s` from piecewise-constant accel and turn rate."""
    speed = np.full_like(t_s, speed0)
    heading = np.full_like(t_s, yaw0)
    t0, s0, h0 = 0.0, speed0, yaw0
    for duration, accel, turn in maneuvers:
        inside = t_s >= t0
        dt = np.clip(t_s[inside] - t0, 0.0, duration)
        speed[inside] = s0 + accel * dt
        heading[inside] = h0 + turn * dt
        t0, s0, h0 = t0 + duration, s0 + accel * duration, h0 + turn * duration
    return speed, heading


def motion(scn: Scenario, t_s: np.ndarray) -> Motion:
    """Sample the scenario's intended motion at times `t_s` (s, increasing, from 0)."""
    t_s = np.asarray(t_s, dtype=float)
    roll0, pitch0, yaw0 = scn.trajectory["attitude_rad"]
    n = t_s.size
    if scn.trajectory["kind"] == "static":
        rpy = np.tile([roll0, pitch0, yaw0], (n, 1))
        return Motion(t_s, np.zeros((n, 3)), np.zeros((n, 3)), rpy)

    # Integrate position on a finer grid, then sample it: velocity is exact, position
    # error of the trapezoid rule is O(dt^2 * v * turn_rate^2), far below a millimetre.
    fine = np.linspace(t_s[0], t_s[-1], (n - 1) * _FINE + 1) if n > 1 else t_s
    speed, heading = _speed_heading(fine, scn.trajectory["speed_mps"], yaw0,
                                    scn.trajectory["maneuvers"])
    if np.any(speed < 0):
        raise UserInputError(f"{scn.source}: [trajectory] maneuvers make the speed negative "
                             f"(min {speed.min():.2f} m/s): expected accelerations that keep speed >= 0")
    v_fine = np.stack([speed * np.cos(heading), speed * np.sin(heading), np.zeros_like(speed)], 1)
    from scipy.integrate import cumulative_trapezoid   # ~0.5 s to import: only a moving profile needs it
    p_fine = cumulative_trapezoid(v_fine, fine, axis=0, initial=0.0)
    idx = np.arange(n) * _FINE if n > 1 else np.arange(n)

    w = 2 * np.pi / scn.trajectory["wave_period_s"]
    t = fine[idx]
    roll = roll0 + scn.trajectory["roll_amplitude_rad"] * np.sin(w * t)
    pitch = pitch0 + scn.trajectory["pitch_amplitude_rad"] * np.sin(w * t + 1.1)
    rpy = np.stack([roll, pitch, heading[idx]], 1)
    return Motion(t_s, p_fine[idx], v_fine[idx], rpy)
