"""GNSS position fix and velocity components in the local ENU frame (m, m/s).

A receiver's geodetic fix is converted to ENU at the edge (runtime geometry). The fix is
the antenna's position: p_enu + C_b_n l_b with the lever arm l_b (parameters `lever_*_m`,
body FLU, from the IMU to the antenna; zeros = co-located). The velocity components are
the IMU's (the lever arm's rotation term omega x l_b is not modelled: at the rates of a
ground vehicle it is below a receiver's velocity noise).
"""
from __future__ import annotations

import casadi as ca

from leonav.models import frames
from leonav.models import registry as R
from leonav.models.state import P, X

_P, _V = X["p_enu"].offset, X["v_enu"].offset


def _fix(name: str, kind_id: int, h, unit: str, token: str, doc: str) -> R.Observable:
    # sigma per fix and axis comes with the data (NMEA GST, NAV-PVT accuracies, a dataset's columns)
    return R.Observable(name, name.lower(), kind_id, h, unit, source="gnss", token=token, stream=token,
                        table="fix", doc=doc)


def antenna_enu(x, p):
    """Antenna position (m, ENU): IMU position plus the body lever arm rotated to ENU."""
    lever_b = ca.vertcat(p[P["lever_x_m"].offset], p[P["lever_y_m"].offset], p[P["lever_z_m"].offset])
    return x[X["p_enu"].slice] + frames.rot_from_quat(x[X["q_nb"].slice]) @ lever_b


def h_pos_e(x, aux, p):
    """East antenna position (m)."""
    return antenna_enu(x, p)[0]


def h_pos_n(x, aux, p):
    """North antenna position (m)."""
    return antenna_enu(x, p)[1]


def h_pos_u(x, aux, p):
    """Up antenna position (m)."""
    return antenna_enu(x, p)[2]


def h_vel_e(x, aux, p):
    """East velocity (m/s)."""
    return x[_V + 0]


def h_vel_n(x, aux, p):
    """North velocity (m/s)."""
    return x[_V + 1]


def h_vel_u(x, aux, p):
    """Up velocity (m/s)."""
    return x[_V + 2]


OBSERVABLES = (
    _fix("POS_E", 1, h_pos_e, "m", "fix", "GNSS fix, antenna East (ENU at the origin)"),
    _fix("POS_N", 2, h_pos_n, "m", "fix", "GNSS fix, antenna North"),
    _fix("POS_U", 3, h_pos_u, "m", "fix", "GNSS fix, antenna Up"),
    _fix("VEL_E", 4, h_vel_e, "m/s", "vel", "GNSS velocity East"),
    _fix("VEL_N", 5, h_vel_n, "m/s", "vel", "GNSS velocity North"),
    _fix("VEL_U", 6, h_vel_u, "m/s", "vel", "GNSS velocity Up"),
)
