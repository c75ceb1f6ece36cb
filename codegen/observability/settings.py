"""Scales, thresholds, the analysis site and parameters, and the motion classes of the structural
observability analysis (package doc)."""
from __future__ import annotations

import math

import numpy as np

from leonav.models import state as S
from leonav.models.constants import WGS84_A_M
from leonav_runtime.observability.naming import TERM_TOL as _TERM_TOL

# --- scaling and thresholds ----------------------------------------------------------------

UNIT_SCALES: dict[str, float] = {
    "m": 1.0,          # position, clock bias
    "m/s": 0.1,        # velocity, clock drift
    "rad": 1e-3,       # attitude (0.06 deg)
    "m/s^2": 1e-3,     # accelerometer bias (~100 ug)
    "rad/s": 1e-5,     # gyro bias (~2 deg/h)
    "Hz": 1.0,         # LO offset
    "s": 1e-2,         # time offset (fix latency, 10 ms)
}
"""Column scale per state unit: one 'typical error' of that unit. A unit not listed scales by 1."""

NOISE_SCALES: dict[str, float] = {"m": 1.0, "m/s": 0.1, "Hz/s": 1.0, "Hz": 1.0}
"""Row scale (nominal 1-sigma noise) per observable unit. A unit not listed scales by 1."""

REL_TOL = 1e-14
"""Rank threshold: a singular value of the scaled O counts when above REL_TOL * the largest.

The double-precision floor of O (roundoff in F, H and the products) is ~1e-16.5 of the largest
singular value at rest and up to 1e-15 in motion (measured over many generic draws), so
REL_TOL sits a decade above it."""
WEAK_TOL = 3e-10
"""A counted direction with a singular value below WEAK_TOL * the largest is flagged *weak*:
observable only through terms ~1e10 times smaller than the best-observed direction (the Earth
rate, the change of gravity's direction along the track). Such a direction carries no useful
information over the window (its sigma is reported)."""
MIN_GAP = 10.0
"""The rank decision is reported 'clear' when sigma_r / sigma_{r+1} >= MIN_GAP."""
TERM_TOL = _TERM_TOL
"""Null-direction terms smaller than this (scaled coordinates, leading term 1) are not named."""

DT_S = 1.0           # analysis step: one IMU interval of the filter's model (s)
N_STEPS = 30         # steps along the motion (measurements at steps 0..N_STEPS)
N_SATS = 6           # satellites per satellite observable (generic geometry)
PHASE_INTERVAL_S = 0.1  # a time-differenced carrier phase spans one tracker epoch before its step (s)
SEED = 20260223
SITE = (math.radians(43.0848638), math.radians(-77.6786127), 170.0)  # the paper's site (rad, rad, m)
GNSS_OBSERVABLES = tuple(m.suffix for m in S.MEASUREMENTS if m.source == "gnss")
"""Observables whose satellites are on GNSS orbits (registry source gnss); every other: LEO."""
GNSS_RADIUS_M = 26_560e3
LEO_RADIUS_M = WGS84_A_M + 550e3
MIN_ELEVATION_RAD = math.radians(20.0)

MOTIONS: dict[str, str] = {
    "static": "at rest, constant attitude",
    "constant-velocity": "straight and level at constant speed and attitude",
    "constant-turn": "level turn at constant speed and turn rate (banked)",
    "accelerating": "speeding up while climbing and turning (acceleration changes direction)",
}
"""Motion classes: name -> description."""




def analysis_params() -> np.ndarray:
    """The parameter vector p of the analysis, from models/: the site, the tactical IMU's and the
    TCXO's noise, every other parameter its registry default (else its example value)."""
    from leonav.models.clock import TCXO
    from leonav.models.imu import TACTICAL

    named = {"lat0_rad": SITE[0], "lon0_rad": SITE[1], "h0_m": SITE[2], "vrw": TACTICAL.vrw, "arw": TACTICAL.arw,
             "acc_bias_rw": TACTICAL.acc_bias_rw, "gyro_bias_rw": TACTICAL.gyro_bias_rw, "q_cdt": TCXO.q_cdt,
             "q_cddt": TCXO.q_cddt, "q_blo": 1e-2, "f_c_hz": 11.325e9}
    p = np.zeros(S.NP)
    for q in S.PARAMS:
        p[S.P[q.name].offset] = named.get(q.name, q.default if q.default is not None else q.example)
    return p
