"""The CasADi functions the analysis evaluates, built once from the models (package doc)."""
from __future__ import annotations

import time
from typing import Callable, Mapping

import casadi as ca

from leonav.models import ekf, frames, kinematics
from leonav.models import state as S
from leonav.models.measurements import models as measurement_models
from leonav.models.measurements.geometry import receiver_ecef

# --- symbolic functions ------------------------------------------------------------------

class Symbolic:
    """The CasADi functions the analysis evaluates, built once from the models (see `symbolic()`).

    step(x, u, dt, p) -> (x_next, F): the filter's nominal step and error-state transition;
    h[suffix](x, aux, p) -> H (1 x NDX); invert(x, u, x_target, dt, p) -> (r, dr/du): velocity
    and attitude residual of mech towards a target; q_from_euler; receiver(x, p) -> (r, v) ECEF;
    mech(x, u, dt, p) -> x_next; boxplus(x, dx); meas[suffix](x, aux, p) -> h.
    """

    def __init__(self, extra_observables: Mapping[str, Callable] | None = None) -> None:
        t0 = time.perf_counter()
        x, u, dt, p = ca.SX.sym("x", S.NX), ca.SX.sym("u", S.NU), ca.SX.sym("dt"), ca.SX.sym("p", S.NP)
        aux, xt, dx = ca.SX.sym("aux", S.NAUX), ca.SX.sym("x_target", S.NX), ca.SX.sym("dx", S.NDX)
        x_next, F, _ = ekf.nav_transition(x, u, dt, p)
        self.step = ca.Function("obs_step", [x, u, dt, p], [x_next, F], ["x", "u", "dt", "p"], ["x_next", "F"])
        models = dict(measurement_models())
        models.update(extra_observables or {})
        self.models = models
        self.h, self.meas = {}, {}
        for suffix, h in models.items():
            h_pred, H = ekf.nav_h(h, x, aux, p)
            self.h[suffix] = ca.Function(f"obs_H_{suffix}", [x, aux, p], [ca.densify(H)], ["x", "aux", "p"], ["H"])
            self.meas[suffix] = ca.Function(f"obs_h_{suffix}", [x, aux, p], [h_pred], ["x", "aux", "p"], ["h"])
        mech = kinematics.mech(x, u, dt, p)
        self.mech = ca.Function("obs_mech", [x, u, dt, p], [mech], ["x", "u", "dt", "p"], ["x_next"])
        dv, dth = S.DX["dv"].slice, S.DX["dtheta"].slice
        err = frames.boxminus(mech, xt)
        r = ca.vertcat(err[dv], err[dth])
        self.invert = ca.Function("obs_invert", [x, u, xt, dt, p], [r, ca.jacobian(r, u)])
        rpy = ca.SX.sym("rpy", 3)
        self.q_from_euler = ca.Function("obs_q", [rpy], [frames.quat_from_euler(rpy)])
        C = kinematics.origin(p)[4]
        self.receiver = ca.Function("obs_rx", [x, p], list(receiver_ecef(x, p)))
        self.boxplus = ca.Function("obs_boxplus", [x, dx], [frames.boxplus(x, dx)])
        self.c_n_e = ca.Function("obs_cne", [p], [C])
        self.build_s = time.perf_counter() - t0


_SYMBOLIC: Symbolic | None = None


def symbolic() -> Symbolic:
    """The process-wide `Symbolic` of the models as they are (built on first use)."""
    global _SYMBOLIC
    if _SYMBOLIC is None:
        _SYMBOLIC = Symbolic()
    return _SYMBOLIC
