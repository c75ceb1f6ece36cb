"""IMU error profiles (SI) used to fill the noise entries of the parameter vector.

Pure Python (no casadi): the runtime reads these to build `p`. The error model is
  increment noise: dtheta_b ~ N(0, arw^2 dt) per axis, dvel_b ~ N(0, vrw^2 dt) per axis;
  biases: random walks with densities acc_bias_rw, gyro_bias_rw;
  initial bias uncertainty: acc_bias_sigma, gyro_bias_sigma (for P0).
A datasheet "bias instability/stability" B is turned into a random walk that reaches B
after `bias_corr_time_s`: rw = B / sqrt(bias_corr_time_s) (a bounded flicker process
modelled as an unbounded random walk over the time scale of a run; stated per profile).
The gyro bias is a random walk unless a profile sets `gyro_bias_tau_s` (then a first-order
Gauss-Markov process: models/state.py `b_g`, models/dynamics.py). The symbolic process noise
built from these is in `models.dynamics`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from leonav.models.constants import DEG_RAD as DEG
from leonav.models.constants import G0_MPS2

HOUR_S = 3600.0


@dataclass(frozen=True)
class ImuProfile:
    """Noise figures of one IMU class, all SI. See the module docstring for the model."""

    name: str
    vrw: float              # m/s/sqrt(s)
    arw: float              # rad/sqrt(s)
    acc_bias_rw: float      # m/s^2/sqrt(s)
    gyro_bias_rw: float     # rad/s/sqrt(s)
    acc_bias_sigma: float   # m/s^2, initial 1-sigma
    gyro_bias_sigma: float  # rad/s, initial 1-sigma
    source: str
    # s: gyro bias correlation time. inf: the random walk of density gyro_bias_rw; finite: a
    # first-order Gauss-Markov process of steady-state sigma gyro_bias_sigma (its driving density
    # is then gyro_bias_sigma sqrt(2 / tau), and gyro_bias_rw is not used)
    gyro_bias_tau_s: float = math.inf


def _profile(name, vrw, arw, acc_bias, gyro_bias, corr_time_s, source) -> ImuProfile:
    return ImuProfile(
        name=name,
        vrw=vrw,
        arw=arw,
        acc_bias_rw=acc_bias / math.sqrt(corr_time_s),
        gyro_bias_rw=gyro_bias / math.sqrt(corr_time_s),
        acc_bias_sigma=acc_bias,
        gyro_bias_sigma=gyro_bias,
        source=source,
    )


# Tactical grade: typical class figures of tactical-grade IMUs (ring-laser / FOG class,
# e.g. HG1700-type units; Groves, "Principles of GNSS, Inertial, and Multisensor Integrated
# Navigation Systems", 2nd ed., ch. 4 gives the same class ranges): ARW 0.1 deg/sqrt(h),
# gyro bias instability 1 deg/h, VRW 0.03 m/s/sqrt(h), accelerometer bias 50 ug.
TACTICAL = _profile(
    "tactical",
    vrw=0.03 / math.sqrt(HOUR_S),
    arw=0.1 * DEG / math.sqrt(HOUR_S),
    acc_bias=50e-6 * G0_MPS2,
    gyro_bias=1.0 * DEG / HOUR_S,
    corr_time_s=HOUR_S,
    source="typical tactical-grade class figures: ARW 0.1 deg/sqrt(h), gyro bias 1 deg/h, "
    "VRW 0.03 m/s/sqrt(h), accel bias 50 ug; bias random walk reaches the bias in 1 h",
)

# Consumer MEMS: WitMotion WT901 (BWT901CL datasheet v20-0707, "Measurement Range &
# Accuracy"): accelerometer stability 0.005 g (accuracy 0.01 g), gyroscope stability
# 0.05 deg/s. The datasheet gives no noise densities; ASSUMED: 300 ug/sqrt(Hz) and
# 0.01 deg/s/sqrt(Hz), the typical densities of the MPU-9250-class MEMS chip in such
# modules. The stabilities are used as bias sigma and reached by the random walk in 100 s.
WT901 = _profile(
    "wt901",
    vrw=300e-6 * G0_MPS2,
    arw=0.01 * DEG,
    acc_bias=0.005 * G0_MPS2,
    gyro_bias=0.05 * DEG,
    corr_time_s=100.0,
    source="WitMotion BWT901CL datasheet v20-0707: accel stability 0.005 g, gyro stability "
    "0.05 deg/s (used as bias sigma, random walk reaching it in 100 s); noise densities not "
    "in the datasheet, assumed 300 ug/sqrt(Hz) and 0.01 deg/s/sqrt(Hz) (MPU-9250-class typical)",
)

PROFILES = {p.name: p for p in (TACTICAL, WT901)}
