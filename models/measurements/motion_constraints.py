"""Motion constraints of a ground vehicle as pseudo-measurements (z = 0, m/s).

- Non-holonomic constraint (NHC): a wheeled vehicle does not slide sideways nor leave the
  ground, so the body-frame velocity v_b = C_b_n^T v_enu has zero lateral (y, left) and
  vertical (z, up) components. Body FLU is the vehicle frame here (the importer rotates
  the IMU axes onto it); the IMU's offset from the axle and wheel slip in turns are left
  to the record's R.
- Zero-velocity update (ZUPT): at a detected standstill the ENU velocity is zero.
Both use the Earth-relative velocity of the state (v_enu), so they hold on a rotating Earth.
"""
from __future__ import annotations

from leonav.models import frames
from leonav.models import registry as R
from leonav.models.state import X


def velocity_body(x):
    """Earth-relative velocity in body FLU axes (m/s): C_b_n^T v_enu."""
    return frames.rot_from_quat(x[X["q_nb"].slice]).T @ x[X["v_enu"].slice]


def h_nhc_y(x, aux, p):
    """Lateral (body left) velocity (m/s); NHC: z = 0."""
    return velocity_body(x)[1]


def h_nhc_z(x, aux, p):
    """Vertical (body up) velocity (m/s); NHC: z = 0."""
    return velocity_body(x)[2]


def h_zupt_e(x, aux, p):
    """East velocity (m/s); ZUPT: z = 0."""
    return x[X["v_enu"].offset + 0]


def h_zupt_n(x, aux, p):
    """North velocity (m/s); ZUPT: z = 0."""
    return x[X["v_enu"].offset + 1]


def h_zupt_u(x, aux, p):
    """Up velocity (m/s); ZUPT: z = 0."""
    return x[X["v_enu"].offset + 2]


def _constraint(name: str, kind_id: int, h, token: str, doc: str) -> R.Observable:
    # z = 0 at the rate and with the sigma of the dataset description's [constraints]
    return R.Observable(name, name.lower(), kind_id, h, "m/s", source="constraint", token=token, stream=token,
                        table="constraint", doc=doc)


OBSERVABLES = (
    _constraint("NHC_Y", 12, h_nhc_y, "nhc", "non-holonomic constraint: lateral body velocity 0"),
    _constraint("NHC_Z", 13, h_nhc_z, "nhc", "non-holonomic constraint: vertical body velocity 0"),
    _constraint("ZUPT_E", 14, h_zupt_e, "zupt", "zero-velocity update at a standstill: East velocity 0"),
    _constraint("ZUPT_N", 15, h_zupt_n, "zupt", "zero-velocity update: North velocity 0"),
    _constraint("ZUPT_U", 16, h_zupt_u, "zupt", "zero-velocity update: Up velocity 0"),
)
