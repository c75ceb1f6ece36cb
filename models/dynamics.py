"""The dynamics of every state block that the mechanization does not drive, from its registry
entry (`models.state.STATES`, `registry.*` dynamics): its mean step over dt and its discrete
process noise. The strapdown predict, the constant-velocity predict and the simulator's truth
(generated `leonav_sensor_error_step`) all use these two functions, so a block's model is
written once (CasADi SX; p is the parameter vector).

- constant: b+ = b, no noise;
- random walk of PSD q: b+ = b, Qd = q dt;
- first-order Gauss-Markov (rate beta, driving density s): b+ = exp(-beta dt) b,
  Qd = s^2 (1 - exp(-2 beta dt)) / (2 beta) = s^2 dt phi(2 beta dt), phi(y) = (1 - e^-y) / y,
  which is the random walk's s^2 dt at beta = 0 (phi(0) = 1 exactly);
- the integral of a random-walk block (a clock bias and its drift): b+ = b + d dt and the exact
  two-state discretization (models.clock.clock_qd).
"""
from __future__ import annotations

import casadi as ca

from leonav.models import registry as R
from leonav.models.clock import clock_qd
from leonav.models.state import DX, P, X


def _par(p, name: str):
    return p[P[name].offset]


def _phi(y):
    """(1 - exp(-y)) / y, exactly 1 at y = 0 (series below 1e-4: error < 1e-13)."""
    return ca.if_else(y < 1e-4, 1 - y / 2 + y * y / 6, -ca.expm1(-y) / y)


def non_navigation() -> list[R.StateBlock]:
    """The blocks the mechanization does not drive, in layout order."""
    from leonav.models.state import STATES

    return [s for s in STATES if not isinstance(s.dynamics, R.Mechanization)]


def block_step(x, dt, p) -> list:
    """Mean step over dt of every non-navigation block of x (SX pieces, layout order)."""
    out = []
    for s in non_navigation():
        b, d = x[X[s.name].slice], s.dynamics
        if isinstance(d, R.GaussMarkov):
            out.append(ca.exp(-_par(p, d.beta) * dt) * b)
        elif isinstance(d, R.Integral):
            out.append(b + x[X[d.of].slice] * dt)
        else:   # constant, random walk
            out.append(b)
    return out


def process_noise(dt, p):
    """Discrete process noise (NDX x NDX) of the non-navigation blocks over dt (module doc);
    zero on the navigation blocks (their noise enters through the IMU increments)."""
    from leonav.models.state import NDX, STATE

    diag = ca.SX.zeros(NDX)
    integrals = []
    for s in non_navigation():
        d, blk = s.dynamics, DX[s.error_name].slice
        if isinstance(d, R.RandomWalk):
            if any(isinstance(o.dynamics, R.Integral) and o.dynamics.of == s.name for o in non_navigation()):
                continue   # the drift of an integral pair: discretized with its bias below
            q = _par(p, d.psd) if d.psd else (_par(p, d.density) ** 2 if d.density else d.psd_value)
            diag[blk] = q * dt
        elif isinstance(d, R.GaussMarkov):
            diag[blk] = _par(p, d.density) ** 2 * dt * _phi(2 * _par(p, d.beta) * dt)
        elif isinstance(d, R.Integral):
            integrals.append(s)
    Q = ca.diag(diag)
    for s in integrals:
        drift = STATE[s.dynamics.of]
        q11, q12, q22 = clock_qd(_par(p, s.dynamics.psd), _par(p, drift.dynamics.psd), dt)
        for k in range(s.nerr):
            i, j = DX[s.error_name].offset + k, DX[drift.error_name].offset + k
            Q[i, i] += q11
            Q[i, j] += q12
            Q[j, i] += q12
            Q[j, j] += q22
    return Q


def error_step(dt, p):
    """(Phi, Qd), NDX x NDX: the transition and process noise of the non-navigation blocks'
    errors over dt (zero rows and columns on the navigation blocks); the simulator draws the
    truth of sensor errors with these (generated `leonav_sensor_error_step`)."""
    from leonav.models.state import NDX, NX

    x = ca.SX.sym("x", NX)
    steps = ca.vertcat(*block_step(x, dt, p))
    blocks = non_navigation()
    cols = ca.vertcat(*[x[X[s.name].slice] for s in blocks])
    J = ca.jacobian(steps, cols)
    Phi = ca.SX(NDX, NDX)
    idx = [DX[s.error_name].offset + k for s in blocks for k in range(s.nerr)]
    for a, i in enumerate(idx):
        for b, j in enumerate(idx):
            if not J[a, b].is_zero():
                Phi[i, j] = J[a, b]
    return Phi, process_noise(dt, p)
