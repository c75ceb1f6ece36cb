"""Observability along a run: the information the measurements carry about the error state.

Numeric counterpart of `codegen.observability` (the structural, symbolic analysis). This
module never imports casadi or `models/`: every F and H comes from the compiled generated
functions (`leonav_predict` gives F, `leonav_h_<k>` gives H), so it runs wherever the filter
runs, on any record stream (simulated scenario, replayed session, dataset).

Along a record stream with linearisation states x_lin (as for `filter.pcrb`: the start of the
interval for an IMU record, the record time for a measurement) it accumulates, without process
noise and without a prior,

    Phi(t) = F_k ... F_0                         (error-state transition from the start)
    W(t)   = sum_i Phi_i^T H_i^T H_i Phi_i / R_i  (observability Gramian of the initial error)

in square-root form (W = R^T R, R updated by QR, so singular values far below sqrt(eps) of the
largest stay accurate), and reports the information about the *current* error state,
J(t) = Phi^-T W Phi^-1, through A(t) = R Phi^-1 S, where S scales each component by a unit
(default: its prior sigma, so an information of 1 equals the prior's):

- singular values of A (sqrt of the eigenvalues of the scaled information) over time, the
  rank (relative threshold `REL_TOL`), the condition number, the weakest directions named;
- per component sigma_info(t): the standard deviation the measurements alone give (a vague
  prior of `VAGUE` units keeps unobservable components finite: they stay near VAGUE units),
  and the time at which it first falls below a target sigma;
- the observability index 1 - posterior / prior variance (prior = S^2, no process noise).

`pcrb_prior_ratios` compares the PCRB (`filter.pcrb`, the driver's `leonav_pcrb_run`) with the
prior propagated without measurements: directions whose bound does not fall below the prior
are the unobservable ones (see docs/observability.md).
"""
from leonav_runtime.observability.gramian import *  # noqa: F401,F403
from leonav_runtime.observability.gramian import _sigma_info  # noqa: F401
from leonav_runtime.observability.naming import *  # noqa: F401,F403
from leonav_runtime.observability.naming import _AXES_BODY, _AXES_ENU, _ROTATION_NAMES  # noqa: F401
from leonav_runtime.observability.report import *  # noqa: F401,F403
