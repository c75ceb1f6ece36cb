"""Starlink beacon carrier phase, time-differenced over one tracker epoch (cycles).

The carrier tracker (leonav_runtime/beacons/carrier*.py) gives each tone's accumulated carrier
phase Phi (cycles) per epoch; its rate is the baseband frequency the SDR sees,

    dPhi/dt = -(1 - s_clk) (f_c/c) rho_dot + b_lo,

with rho the range to the satellite (ECEF), s_clk the SDR sample clock's fractional frequency
error (a clock fast by s counts an interval T of its samples in T / (1 + s) true seconds, so
every frequency it measures is scaled by 1 - s to first order) and b_lo the front end's common
frequency offset at baseband as the SDR measures it (LNB LO + tuner, Hz: the Doppler model's
state, whose own scale error it absorbs). Scaling b_lo by 1 - s as well would make h bilinear in
two states with wide priors (1e-4 x 5 kHz per epoch = 0.5 cycles, 40 sigma: a first update from
the prior would lock in that error); as written h is linear in both.
The measurement is the difference over one epoch interval T = aux `dt_phase`:

    z = Phi(t) - Phi(t - T),
    h = -(1 - s_clk) (f_c/c) (rho(t) - rho(t - T)) + T b_lo - s_clk T df,

with rho the one-way light-time range of each end: the phase received at t left the satellite
at t - tau, so rho = |r_tx - r_U| + the Sagnac term (w_ie/c)(x_tx y_U - y_tx x_U), r_tx the
satellite at transmit time (`transmit_state`). The satellite's positions at both ends come from
the ephemeris (aux `r_S_ecef` at t and `r_S_prev_ecef` at t - T: a Taylor step from t would
miss by ~1 mm over 0.1 s, a third of the noise); the receiver at t - T is the state moved back
along its velocity and acceleration (aux `f_b`), r_U - v_U T + a_U T^2/2 (a car's jerk leaves
< 0.2 mm at T = 0.1 s). The simulator's truth is the exact light-time solution with the Earth's
rotation as a rotation (leonav_runtime/simulation/carrier_truth.py), not this model.

Why time-differenced and not a per-pass ambiguity state (docs/carrier.md, "Into the filter"):
the integer ambiguity and the LO phase both cancel in the difference, so the state keeps a
fixed size whatever the number of tracked passes (45 satellites would otherwise add 45 states
to a dense 22-state covariance), and a cycle slip costs one epoch instead of a re-initialized
state. The LO phase wander inside an epoch that b_lo's random walk does not follow is common
to every satellite of the epoch; the filter's b_lo absorbs its mean over T.

A tone df Hz off the channel centre (aux `df_tone`; an outer tone of the comb: k x 44 kHz) is
referred to the centre by the road before it gets here (z - T df + (df/c) drho_pred,
`inputs.carrier_phase.tone_to_centre`), but the SDR counts the tone's offset on its own clock,
(1 - s_clk) df: the -s_clk T df left over is h's last term (1.8 cycles for k = 4 at 100 ppm,
45 sigma; 0.018 cycles at a TCXO's 1 ppm). The reference's own s_clk (df/c) drho is below 1e-4
cycles and left out. df_tone = 0 is the centre tone and the simulator's records.

The sample clock is warm-TCXO class on an RTL-SDR V3 (<= 1 ppm) and up to ~100 ppm without;
the time tags are taken as disciplined (the host clock restamps each capture block), so s_clk
scales the measured frequencies and not the time axis.
"""
from __future__ import annotations

import casadi as ca

from leonav.models import kinematics
from leonav.models import registry as R
from leonav.models.constants import C_LIGHT_MPS, OMEGA_IE_RADPS
from leonav.models.measurements.geometry import receiver_ecef, transmit_state
from leonav.models.state import AUX, P, X

PARAMS = (
    R.Param("q_sclk", "1/s", "SDR sample-clock fractional frequency random-walk PSD (warm TCXO: 1 ppm over hours)",
            default=1e-16, example=1e-16),
)
STATES = (
    R.StateBlock("s_clk", 1, "-", "SDR sample-clock fractional frequency error (+1e-6: 1 ppm fast)",
                 R.RandomWalk(psd="q_sclk"),
                 R.Prior(1e-4, doc="an RTL-SDR without a TCXO: up to ~100 ppm"), fd_step=1e-7, typical=1e-5,
                 truth=R.Truth("starlink.sample_clock_error", "own"),
                 error_doc="sample-clock fractional frequency error"),
)


def light_time_range(r_S, v_S, a_S, r_U):
    """One-way range (m) of a signal received at r_U from the satellite whose state at reception
    is (r_S, v_S, a_S), all ECEF: |r_tx - r_U| plus the Sagnac term of the flight."""
    r_tx, _, _ = transmit_state(r_S, v_S, a_S, r_U)
    return ca.norm_2(r_tx - r_U) + OMEGA_IE_RADPS / C_LIGHT_MPS * (r_tx[0] * r_U[1] - r_tx[1] * r_U[0])


def h(x, aux, p):
    """Predicted carrier-phase change (cycles) over the epoch interval aux `dt_phase` (s)."""
    r_U, v_U = receiver_ecef(x, p)
    a_U = kinematics.receiver_accel_ecef(x, aux, p)
    T = aux[AUX["dt_phase"].offset]
    v_S, a_S = aux[AUX["v_S_ecef"].slice], aux[AUX["a_S_ecef"].slice]
    rho = light_time_range(aux[AUX["r_S_ecef"].slice], v_S, a_S, r_U)
    rho_prev = light_time_range(aux[AUX["r_S_prev_ecef"].slice], v_S - a_S * T, a_S,
                                r_U - v_U * T + 0.5 * a_U * T**2)
    f_c = p[P["f_c_hz"].offset]
    s_clk, df = x[X["s_clk"].offset], aux[AUX["df_tone"].offset]
    return -(1 - s_clk) * (f_c / C_LIGHT_MPS) * (rho - rho_prev) + T * x[X["b_lo"].offset] - s_clk * T * df


OBSERVABLES = (
    R.Observable("CARRIER_PHASE", "carrier_phase", 20, h, "cyc", source="leo", token="phase", stream="carrier_phase",
                 table="satellite", constellation="starlink",
                 # a PLL at 25 dB-Hz with a 10 Hz loop: ~10 deg per epoch, sqrt(2) of it in a difference
                 noise=R.Noise("starlink.carrier_phase_sigma_cyc", 0.04, 1e-5, 10.0,
                               "time-differenced carrier-phase noise (cycles)"),
                 doc="Starlink beacon carrier phase, time-differenced over one tracker epoch (beyond the paper)"),
)
