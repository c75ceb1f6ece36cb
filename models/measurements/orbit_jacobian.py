"""Jacobian of a satellite observable with respect to the satellite states it reads from aux.

The consider (Schmidt) treatment of ephemeris error needs dh/d(satellite state): the
orbit error is not a filter state, its covariance P_sat (ECEF) enters each record as
R + J P_sat J^T. J is taken from the same h(x, aux, p) the filter uses, so the term
cannot drift from the measurement model. Columns (1 x 12): dh/dr_S (unit of z per m), dh/dv_S (per m/s), dh/dr_ref, dh/dv_ref, all ECEF; the reference blocks are zero for
an observable that does not read them. The acceleration blocks are left out: an orbit
error of a km changes the satellite's gravity acceleration by ~1e-3 m/s^2, and the runtime's
orbit-error model (leonav_runtime/inputs/consider.py) carries none.
"""
from __future__ import annotations

import casadi as ca

from leonav.models.state import AUX

ORBIT_BLOCKS = ("r_S_ecef", "v_S_ecef", "r_ref_ecef", "v_ref_ecef")
"""The aux blocks differentiated, in the order of the Jacobian's columns."""
NORBIT = sum(AUX[name].size for name in ORBIT_BLOCKS)


def orbit_jacobian(h_value, aux):
    """(1, NORBIT) d h / d [r_S, v_S, r_ref, v_ref] of a scalar SX expression of symbolic aux.

    A time-differenced observable also reads the satellite's position T = aux `dt_phase` earlier
    (`r_S_prev_ecef`), from the same orbit: an orbit error (dr, dv) at t moves it by dr - T dv,
    so its derivative is folded into the r_S and v_S columns."""
    J = [ca.jacobian(h_value, aux[AUX[name].slice]) for name in ORBIT_BLOCKS]
    J_prev = ca.jacobian(h_value, aux[AUX["r_S_prev_ecef"].slice])
    J[0] = J[0] + J_prev
    J[1] = J[1] - aux[AUX["dt_phase"].offset] * J_prev
    return ca.horzcat(*J)


def reads_orbit(h_value, aux) -> bool:
    """Whether the expression depends on a satellite's position or velocity in aux."""
    return any(ca.depends_on(h_value, aux[AUX[name].slice]) for name in ORBIT_BLOCKS + ("r_S_prev_ecef",))


def orbit_observables() -> tuple[str, ...]:
    """Suffixes of the observables whose h reads a satellite state from aux (models.state
    order): the ones that get a generated `leonav_orbit_jac_<suffix>`."""
    from leonav.models.measurements import models
    from leonav.models.state import NAUX, NP, NX

    x, aux, p = ca.SX.sym("x", NX), ca.SX.sym("aux", NAUX), ca.SX.sym("p", NP)
    return tuple(k for k, h in models().items() if reads_orbit(h(x, aux, p), aux))
