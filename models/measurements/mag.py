"""Magnetometer heading: the direction of the body's forward axis from magnetic North, as the
unit vector [cos, sin] of the magnetic yaw (no angle wrap in the filter's innovation).

    psi_mag = psi + D,   z = [cos psi_mag, sin psi_mag]

psi is the true yaw of the body x-axis (from East towards North, the state's convention,
taken from the attitude's forward column) and D the magnetic declination (rad, positive when
magnetic North lies East of true North; the parameter `mag_declination_rad`, scenario key
`[mag] declination_deg`). A calibrated magnetometer's heading error (hard/soft iron residue,
local disturbances) is the noise, on each component; no bias state is modelled.

Modes add the word `mag` after imu: `gps+imu+mag`, `leo-alpha+imu+mag`.
"""
from __future__ import annotations

import casadi as ca

from leonav.models import frames
from leonav.models import registry as R
from leonav.models.state import P, X

PARAMS = (
    R.Param("mag_declination_rad", "rad", "magnetic declination at the site (positive East)", default=0.0,
            example=0.2, scenario="mag.declination_deg", lo=-180.0, hi=180.0),
)


def _heading(x, p):
    """(cos, sin) of the magnetic yaw of the body's forward axis."""
    forward = frames.rot_from_quat(x[X["q_nb"].slice])[:, 0]
    norm = ca.sqrt(forward[0] ** 2 + forward[1] ** 2)
    c, s = forward[0] / norm, forward[1] / norm
    d = p[P["mag_declination_rad"].offset]
    return c * ca.cos(d) - s * ca.sin(d), s * ca.cos(d) + c * ca.sin(d)


def h_cos(x, aux, p):
    """cos of the magnetic yaw (-)."""
    return _heading(x, p)[0]


def h_sin(x, aux, p):
    """sin of the magnetic yaw (-)."""
    return _heading(x, p)[1]


_NOISE = R.Noise("mag.sigma_deg", 2.0, 0.01, 90.0, "1-sigma heading noise of a calibrated magnetometer")
OBSERVABLES = (
    R.Observable("MAG_COS", "mag_cos", 18, h_cos, "-", source="local", token="mag", stream="mag", table="local",
                 rate_hz=10.0, noise=_NOISE, doc="magnetometer heading, cos of the magnetic yaw"),
    R.Observable("MAG_SIN", "mag_sin", 19, h_sin, "-", source="local", token="mag", stream="mag", table="local",
                 rate_hz=10.0, noise=_NOISE, doc="magnetometer heading, sin of the magnetic yaw"),
)
