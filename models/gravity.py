"""WGS84 normal gravity (Somigliana with the second-order height term)."""
from __future__ import annotations

import casadi as ca

from leonav.models import constants as K


def normal_gravity(lat, h):
    """Magnitude of normal gravity (m/s^2) at geodetic latitude `lat` (rad), height `h` (m).

    Somigliana's closed formula on the ellipsoid, times the height series
    1 - 2/a (1 + f + m - 2 f sin^2 lat) h + 3 h^2 / a^2 (WGS84, TR8350.2 eq. 4-3).
    Normal gravity includes the centrifugal acceleration of the Earth's rotation.
    """
    return normal_gravity_sin(ca.sin(lat), h)


def normal_gravity_sin(sin_lat, h):
    """`normal_gravity` from sin(lat) instead of lat (it depends on sin^2 lat only)."""
    s2 = sin_lat * sin_lat
    g0 = K.GAMMA_E_MPS2 * (1 + K.SOMIGLIANA_K * s2) * ca.sqrt(1 / (1 - K.WGS84_E2 * s2))
    a = K.WGS84_A_M
    return g0 * (1 - 2 / a * (1 + K.WGS84_F + K.GRAVITY_M - 2 * K.WGS84_F * s2) * h + 3 / (a * a) * h * h)
