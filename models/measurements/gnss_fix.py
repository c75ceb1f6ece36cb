"""GNSS position fix and velocity components in the local ENU frame (m, m/s).

A receiver's geodetic fix is converted to ENU at the edge (runtime geometry). The fix is the
antenna's position, p_enu + C_b_n l_b with the lever arm l_b (parameters `lever_*_m`, body FLU,
from the IMU to the antenna; zeros = co-located), its velocity v_enu + C_b_n (w x l_b) with w the
body rate (aux `w_b`, bias-corrected here).

Fix latency: a fix tagged t on the IMU's time axis is the antenna at t - dt_fix. It is applied at
the state of the latest IMU sample, aux `dt_tag` before t, so the models look back by
dt_fix - dt_tag (s) to first order: position - v (dt_fix - dt_tag), velocity - a (dt_fix - dt_tag)
(a the Earth-relative acceleration from the specific force in aux `f_b`). With dt_tag the fix is
placed at its tag even between IMU samples (up to one IMU interval, 10 ms at 100 Hz, otherwise). `dt_fix` is estimated
when a run asks for it (`[gnss] time_offset_s = "estimate"`: a prior sigma); a known latency
shifts the time tags instead and the state stays at zero with a zero prior, so the models are
those without it. It is observable from the IMU's motion: a latency looks like a position error
along the velocity, which turns and speed changes tell apart from a position offset.
"""
from __future__ import annotations

import casadi as ca

from leonav.models import frames, kinematics
from leonav.models import registry as R
from leonav.models.state import AUX, P, X

PARAMS = (
    # zero unless a run estimates the latency: a known (or absent) latency must stay exactly zero
    R.Param("dt_fix_rw", "s/sqrt(s)", "fix latency random walk (0: frozen; the runtime sets it when estimating)",
            default=0.0, example=1e-4),
)
STATES = (
    R.StateBlock("dt_fix", 1, "s", "GNSS fix latency: a fix tagged t is the antenna at t - dt_fix",
                 R.RandomWalk(density="dt_fix_rw"),
                 R.Prior(0.0, doc="0: a known latency (the tags are shifted); a run estimating it sets the sigma"),
                 fd_step=1e-3, typical=0.1, truth=R.Truth("zero", "none"), error_doc="fix latency error"),
)


def _fix(name: str, kind_id: int, h, unit: str, token: str, doc: str) -> R.Observable:
    # sigma per fix and axis comes with the data (NMEA GST, NAV-PVT accuracies, a dataset's columns)
    return R.Observable(name, name.lower(), kind_id, h, unit, source="gnss", token=token, stream=token,
                        table="fix", doc=doc)


def _lever(p):
    return ca.vertcat(p[P["lever_x_m"].offset], p[P["lever_y_m"].offset], p[P["lever_z_m"].offset])


def antenna_enu(x, p):
    """Antenna position (m, ENU): IMU position plus the body lever arm rotated to ENU."""
    return x[X["p_enu"].slice] + frames.rot_from_quat(x[X["q_nb"].slice]) @ _lever(p)


def _look_back(x, aux):
    """How long before the state's time the measured antenna was (s): the latency less the tag's
    lead over the state (aux dt_tag: a fix between IMU samples is applied at the latest one)."""
    return x[X["dt_fix"].offset] - aux[AUX["dt_tag"].offset]


def antenna_at_fix_time(x, aux, p):
    """The antenna position where a late fix measured it (m, ENU), to first order in the look-back."""
    return antenna_enu(x, p) - x[X["v_enu"].slice] * _look_back(x, aux)


def antenna_velocity(x, aux, p):
    """Antenna velocity (m/s, ENU) at the fix time: v + C_b_n ((w_b - b_g) x l_b) - a * look-back."""
    C = frames.rot_from_quat(x[X["q_nb"].slice])
    w = aux[AUX["w_b"].slice] - x[X["b_g"].slice]
    a = kinematics.accel_enu(x, aux[AUX["f_b"].slice], p)
    return x[X["v_enu"].slice] + C @ ca.cross(w, _lever(p)) - a * _look_back(x, aux)


def h_pos_e(x, aux, p):
    """East antenna position (m)."""
    return antenna_at_fix_time(x, aux, p)[0]


def h_pos_n(x, aux, p):
    """North antenna position (m)."""
    return antenna_at_fix_time(x, aux, p)[1]


def h_pos_u(x, aux, p):
    """Up antenna position (m)."""
    return antenna_at_fix_time(x, aux, p)[2]


def h_vel_e(x, aux, p):
    """East antenna velocity (m/s)."""
    return antenna_velocity(x, aux, p)[0]


def h_vel_n(x, aux, p):
    """North antenna velocity (m/s)."""
    return antenna_velocity(x, aux, p)[1]


def h_vel_u(x, aux, p):
    """Up antenna velocity (m/s)."""
    return antenna_velocity(x, aux, p)[2]


OBSERVABLES = (
    _fix("POS_E", 1, h_pos_e, "m", "fix", "GNSS fix, antenna East (ENU at the origin)"),
    _fix("POS_N", 2, h_pos_n, "m", "fix", "GNSS fix, antenna North"),
    _fix("POS_U", 3, h_pos_u, "m", "fix", "GNSS fix, antenna Up"),
    _fix("VEL_E", 4, h_vel_e, "m/s", "vel", "GNSS velocity of the antenna, East"),
    _fix("VEL_N", 5, h_vel_n, "m/s", "vel", "GNSS velocity of the antenna, North"),
    _fix("VEL_U", 6, h_vel_u, "m/s", "vel", "GNSS velocity of the antenna, Up"),
)
