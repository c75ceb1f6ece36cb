"""Consider (Schmidt) term of satellite orbit error: R_eff = R + J P_sat J^T per record.

The satellite states in aux come from orbital elements whose error is known only
statistically: 1-sigma radial / along-track / cross-track offsets (m) of the orbit. They
are not filter states (a consider state per satellite would grow the layout by 6 per
satellite in view); their effect enters each record's R through the Jacobian of the same
generated h over the aux satellite states (`leonav_orbit_jac_<kind>`, no casadi here).

P_sat (6 x 6, ECEF, [r, v]) is the linearisation of the orbit-error model the simulator
uses (leonav_runtime/simulation/realism.py `perturb_states`): with R, A, C the satellite's own
radial, along-track and cross-track unit axes (rows of `rac_axes`),
  radial and cross-track errors move the position:  dr = d_R R + d_C C,  dv = 0;
  an along-track error is a time shift dt = d_A / (v.A) along the orbit: dr = v dt, dv = a dt,
so G = d[r, v]/d[d_R, d_A, d_C] and P_sat = G diag(sigma_rac^2) G^T. The velocity error of
the time shift, |a| sigma_A / |v| ~ n sigma_A (n the mean motion, ~1.1e-3 rad/s for
Starlink: ~1 m/s for 960 m along-track), is radial; the velocity counterparts of radial and
cross-track offsets in a real orbit (n sigma_R, n sigma_C, ~0.2-0.3 m/s) are left out, as in
the simulated truth. A differenced observable (OFDM range difference) also carries its
reference satellite's error, independent of the satellite's.

The errors are treated as white between records: no cross-covariance between the
navigation state and an orbit error is carried, so the term is a geometry-aware,
model-derived R inflation. With a correlation time (`OrbitConsider.correlation_s`) the
per-record term is multiplied by m, the records of its satellite within that time (they
share its error, constant over a pass): for m records of the same sensitivity that gives
exactly the information of their mean, 1 / (sigma_orbit^2 + R / m), where the white term
claims m / (sigma_orbit^2 + R), up to m times too much (see docs/scenarios.md).
The Jacobian is evaluated at one receiver state (the prior's; the filter's estimate is not
known when records are built): it depends on the receiver mainly through the line of sight
over ranges of 500+ km. On maritime-outage (the ship moves 2.5 km in 360 s) the consider
sigma at the prior differs from the one at the true position by 0.4 % (median), 5 % at most.

Where an operator publishes the orbit's covariance (orbits/operator_states.py), P_sat is that
covariance instead of the model's: `OrbitConsider.covariance` maps a kind to a provider of
per-record ECEF covariances; records it does not cover keep the model's term (or none).
"""
from __future__ import annotations

import dataclasses

import numpy as np


def rac_axes(state9: np.ndarray) -> np.ndarray:
    """(n, 3, 3) unit radial, along-track, cross-track axes (rows) of states (n, 9) [r v a]
    (ECEF, m, m/s, m/s^2)."""
    r, v = state9[:, 0:3], state9[:, 3:6]
    R = r / np.linalg.norm(r, axis=1, keepdims=True)
    C = np.cross(r, v)
    C /= np.linalg.norm(C, axis=1, keepdims=True)
    return np.stack([R, np.cross(C, R), C], axis=1)


def orbit_error_map(state9: np.ndarray) -> np.ndarray:
    """(n, 6, 3) G = d[r, v]/d[d_R, d_A, d_C]: the ECEF position (m) and velocity (m/s) error
    per metre of radial, along-track (a time shift along the orbit) and cross-track error."""
    axes = rac_axes(state9)
    v, a = state9[:, 3:6], state9[:, 6:9]
    dt_per_m = 1.0 / np.einsum("ni,ni->n", v, axes[:, 1])          # s of time shift per m along-track
    G = np.zeros((state9.shape[0], 6, 3))
    G[:, 0:3, 0] = axes[:, 0]
    G[:, 0:3, 1] = v * dt_per_m[:, None]
    G[:, 3:6, 1] = a * dt_per_m[:, None]
    G[:, 0:3, 2] = axes[:, 2]
    return G


def orbit_covariance(state9: np.ndarray, sigma_rac_m: np.ndarray) -> np.ndarray:
    """(n, 6, 6) P_sat of [r, v] (ECEF; m^2, m^2/s, m^2/s^2) for 1-sigma radial, along, cross
    errors sigma_rac_m (3,) m at satellite states (n, 9)."""
    G = orbit_error_map(state9) * np.asarray(sigma_rac_m, float)[None, None, :]
    return G @ np.transpose(G, (0, 2, 1))


def consider_variance(J: np.ndarray, sat9: np.ndarray, ref9: np.ndarray | None,
                      sigma_rac_m: np.ndarray) -> np.ndarray:
    """(n,) J P_sat J^T (unit of z squared) per record: J (n, 12) from
    `NavFunctions.orbit_jacobian_many`, the satellite states (n, 9) and, for a differenced
    observable, the reference's (n, 9) with its own independent error (None: no reference)."""
    def quad(Jb, state9):
        Jg = np.einsum("ni,nij->nj", Jb, orbit_error_map(state9)) * np.asarray(sigma_rac_m, float)
        return np.einsum("nj,nj->n", Jg, Jg)
    var = quad(J[:, 0:6], sat9)
    if ref9 is not None and np.any(J[:, 6:12]):
        var = var + quad(J[:, 6:12], ref9)
    return var


def covariance_variance(J: np.ndarray, p_sat: np.ndarray, p_ref: np.ndarray | None) -> np.ndarray:
    """(n,) J P J^T per record for given ECEF covariances of [r, v] (n, 6, 6) of the satellite
    and, for a differenced observable, of its reference (None: no reference)."""
    var = np.einsum("ni,nij,nj->n", J[:, 0:6], p_sat, J[:, 0:6])
    if p_ref is not None:
        var = var + np.einsum("ni,nij,nj->n", J[:, 6:12], p_ref, J[:, 6:12])
    return var


def records_per_satellite(sat_id: np.ndarray, t: np.ndarray, correlation_s: float) -> np.ndarray:
    """(n,) m per record: how many records of its satellite lie within the error's correlation
    time (s) centred on it (1 when correlation_s is 0: white errors)."""
    m = np.ones(sat_id.size)
    if correlation_s <= 0 or not sat_id.size:
        return m
    for sid in np.unique(sat_id):
        idx = np.flatnonzero(sat_id == sid)
        ts = t[idx]
        lo = np.searchsorted(ts, ts - 0.5 * correlation_s, side="left")
        hi = np.searchsorted(ts, ts + 0.5 * correlation_s, side="right")
        m[idx] = hi - lo
    return m


@dataclasses.dataclass(frozen=True)
class OrbitConsider:
    """What the road needs for the consider term: per observable kind ("doppler_rate", ...)
    the 1-sigma radial, along-track, cross-track orbit error (3,) m of its satellites, and
    the error's correlation time (s; 0 = white between records). covariance: per kind, a
    provider of the orbit's own covariance, `covariance_ecef(sat_id or None, t, state9)` ->
    (n, 6, 6) ECEF [r, v] (NaN where it has none; sat_id None: identify the satellites by
    their states, as for a differenced observable's reference); it wins over sigma_rac_m."""

    sigma_rac_m: dict
    correlation_s: float = 0.0
    covariance: dict = dataclasses.field(default_factory=dict)

    def variance(self, table, aux: np.ndarray, x_rx: np.ndarray, params: np.ndarray, nav) -> np.ndarray | None:
        """(n,) variance (unit of z squared) the orbit error adds to each record of satellite
        `table` with aux rows (n, NAUX), Jacobian at receiver state x_rx (NX,); None when the
        table's kind has no sigma here."""
        sig = self.sigma_rac_m.get(table.KIND)
        provider = self.covariance.get(table.KIND)
        if (sig is None and provider is None) or not table.t.size:
            return None
        J = nav.orbit_jacobian_many(table.KIND, x_rx, aux, params)
        if provider is None:
            var = consider_variance(J, table.sat_ecef, table.ref_ecef, sig)
        else:
            t = np.asarray(table.t, float)
            p_sat = provider.covariance_ecef(np.asarray(table.sat_id), t, table.sat_ecef)
            reads_ref = table.ref_ecef is not None and np.any(J[:, 6:12])
            p_ref = provider.covariance_ecef(None, t, table.ref_ecef) if reads_ref else None
            var = covariance_variance(J, np.nan_to_num(p_sat), None if p_ref is None else np.nan_to_num(p_ref))
            uncovered = ~np.isfinite(p_sat).all(axis=(1, 2))
            if p_ref is not None:
                uncovered |= ~np.isfinite(p_ref).all(axis=(1, 2))
            if uncovered.any() and sig is not None:     # the model's term where the operator has none
                sub = np.flatnonzero(uncovered)
                var[sub] = consider_variance(J[sub], table.sat_ecef[sub],
                                             None if table.ref_ecef is None else table.ref_ecef[sub], sig)
        return var * records_per_satellite(np.asarray(table.sat_id), np.asarray(table.t, float), self.correlation_s)
