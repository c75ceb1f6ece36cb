"""The casadi.Functions that are generated to C, with named inputs and outputs.

Names and signatures are the contract of docs/design.md. Every output of a function the
runtime calls is dense (densified) and every matrix is stored column-major in the generated
C. Each function is generated into its own C file (codegen/emit_c.py); a function that calls
another generated function (an update calls the shared Joseph step, the PCRB information add
calls the observable's h, the predict calls its three stages) reaches it through `call`:
for generation an external reference (the callee's own file, linked), for evaluation in
Python the callee itself.
"""
from __future__ import annotations

from typing import Callable

import casadi as ca

from leonav.codegen.emit_pipeline import Pipeline, Step
from leonav.models import dynamics, ekf, frames, input_noise, kinematics
from leonav.models.measurements import gnss_code
from leonav.models.measurements import models as measurement_models
from leonav.models.measurements.geometry import receiver_ecef, transmit_state
from leonav.models.measurements.orbit_jacobian import orbit_jacobian, orbit_observables
from leonav.models.state import NAUX, NDX, NP, NU, NX
from leonav.models.state import P as P_BLOCK

FUNCTION_OPTS = {"cse": True}


def _fn(name: str, inputs: dict, outputs: dict, doc: str, dense: bool = True) -> ca.Function:
    fn = ca.Function(
        name,
        list(inputs.values()),
        [ca.densify(v) if dense else v for v in outputs.values()],
        list(inputs.keys()),
        list(outputs.keys()),
        FUNCTION_OPTS,
    )
    fn.doc = doc  # kept for the manifest (casadi ignores it)
    return fn


def _syms():
    return {
        "x": ca.SX.sym("x", NX),
        "P": ca.SX.sym("P", NDX, NDX),
        "u": ca.SX.sym("u", NU),
        "dt": ca.SX.sym("dt"),
        "p": ca.SX.sym("p", NP),
        "aux": ca.SX.sym("aux", NAUX),
        "z": ca.SX.sym("z"),
        "R": ca.SX.sym("R"),
    }


def _itself(fn: ca.Function) -> ca.Function:
    return fn


def build_functions(call: Callable[[ca.Function], ca.Function] = _itself) -> list[ca.Function]:
    """All generated functions, in a fixed order (callees before their callers).

    The filter steps are SX (straight-line C) with the covariance algebra built on the
    structural non-zeros of F and H and on the symmetry of P (see models.ekf): generic dense
    18 x 18 products (MX, casadi_mtimes loops) were several times slower. Each update is
    glue over its SX innovation and one shared SX Joseph function; the predict
    is glue over its three SX stages (models.ekf.nav_predict). `call(fn)`:
    how a caller references a generated callee (module doc).
    """
    s = _syms()
    x, P, u, dt, p, aux, z, R = (s[k] for k in ("x", "P", "u", "dt", "p", "aux", "z", "R"))
    out: list[ca.Function] = []

    out.append(_fn("leonav_mech", {"x": x, "u": u, "dt": dt, "p": p},
                   {"x_next": kinematics.mech(x, u, dt, p)},
                   "nominal strapdown mechanization over one IMU interval"))
    out += _predict_functions(call, x, P, u, dt, p)
    x_cv, P_cv, F_cv, Qd_cv = ekf.cv_predict(x, P, dt, p)
    out.append(_fn("leonav_predict_cv", {"x": x, "P": P, "dt": dt, "p": p},
                   {"x_next": x_cv, "P_next": P_cv, "F": F_cv, "Qd": Qd_cv},
                   "constant-velocity predict (no IMU): white acceleration of PSD vrw^2, clock, P_next = F P F^T + Qd"))
    # update_k = innovation_k (h, H and b = P H^T on H's non-zeros, SX) followed by one
    # shared SX Joseph function: its O(n^2) code is compiled once, not once per observable
    # (ten inlined copies took `cc -O2` from ~9 to ~20 s for ~0.14 us less per update).
    y_s, b_s, S_s = ca.SX.sym("y"), ca.SX.sym("b", NDX), ca.SX.sym("S")
    joseph_fn = _fn("leonav_joseph", {"x": x, "P": P, "y": y_s, "b": b_s, "S": S_s},
                    dict(zip(("x_post", "P_post"), ekf.joseph_update(x, P, y_s, b_s, S_s, frames.boxplus))),
                    "shared Joseph-form step of every scalar update: K = b / S, x [+] K y, "
                    "P - K c^T - c K^T with c = b - S K / 2")
    out.append(joseph_fn)
    xm, Pm, pm = (ca.MX.sym(n, *v.shape) for n, v in (("x", x), ("P", P), ("p", p)))
    auxm, zm, Rm, Jm = ca.MX.sym("aux", NAUX), ca.MX.sym("z"), ca.MX.sym("R"), ca.MX.sym("J", NDX, NDX)
    for suffix, h in measurement_models().items():
        h_pred, H = ekf.nav_h(h, x, aux, p)
        hfn = _fn(f"leonav_h_{suffix}", {"x": x, "aux": aux, "p": p}, {"h": h_pred, "H": H},
                  f"{suffix}: prediction and 1 x NDX Jacobian w.r.t. dx at 0")
        out.append(hfn)
        out += _update_functions(call, suffix, ekf.innovation(P, z, R, h_pred, H), joseph_fn,
                                 (x, P, z, R, aux, p), (xm, Pm, zm, Rm, auxm, pm))
        # not on the filter path: MX keeps the dense J + H^T H / R a loop
        _, Hm = call(hfn)(xm, auxm, pm)
        out.append(_fn(f"leonav_pcrb_info_{suffix}", {"J": Jm, "x": xm, "aux": auxm, "p": pm, "R": Rm},
                       {"J_next": ekf.information_add(Jm, Hm, Rm)},
                       f"{suffix}: Fisher information add J + H^T H / R"))

    # PCRB measurement step for any observable, H from its leonav_h_<k>: MX (dense loops,
    # a few lines of C; the bound is not on the filter's hot path)
    Bm, Hm = ca.MX.sym("B", NDX, NDX), ca.MX.sym("H", 1, NDX)
    B_next, S_b = ekf.information_step(Bm, Hm, Rm)
    out.append(_fn("leonav_pcrb_update", {"B": Bm, "H": Hm, "R": Rm}, {"B_next": B_next, "S": S_b},
                   "PCRB measurement step on B = J^-1 (Sherman-Morrison): B - B H^T H B / S, S = H B H^T + R"))

    dx = ca.SX.sym("dx", NDX)
    x0 = ca.SX.sym("x0", NX)
    out.append(_fn("leonav_boxplus", {"x": x, "dx": dx}, {"x_out": frames.boxplus(x, dx)},
                   "retraction x [+] dx (attitude: q (x) exp(dtheta/2))"))
    out.append(_fn("leonav_boxminus", {"x1": x, "x0": x0}, {"dx": frames.boxminus(x, x0)},
                   "error x1 [-] x0 (attitude: body-frame rotation vector)"))
    rpy = ca.SX.sym("rpy", 3)
    q = ca.SX.sym("q", 4)
    out.append(_fn("leonav_q_from_euler", {"rpy": rpy}, {"q": frames.quat_from_euler(rpy)},
                   "q_nb from roll, pitch, yaw (rad), C_b_n = Rz(yaw) Ry(pitch) Rx(roll)"))
    out.append(_fn("leonav_euler_from_q", {"q": q}, {"rpy": frames.euler_from_quat(q)},
                   "roll, pitch, yaw (rad) of q_nb"))

    p_enu = ca.SX.sym("p_enu", 3)
    f_b = ca.SX.sym("f_b", 3)
    out.append(_fn("leonav_gravity_enu", {"p_enu": p_enu, "p": p}, {"g_enu": kinematics.gravity_enu(p_enu, p)},
                   "normal gravity vector (m/s^2) at p_enu, origin ENU axes"))
    out.append(_fn("leonav_earth_rate_enu", {"p": p}, {"w_ie_enu": kinematics.earth_rate_enu(p)},
                   "Earth rotation rate (rad/s) in the origin ENU axes"))
    out.append(_fn("leonav_accel_enu", {"x": x, "f_b": f_b, "p": p}, {"a_enu": kinematics.accel_enu(x, f_b, p)},
                   "Earth-relative acceleration d v_enu/dt (m/s^2) for specific force f_b (body)"))
    r_U, v_U = receiver_ecef(x, p)
    out.append(_fn("leonav_receiver_ecef", {"x": x, "p": p}, {"r_ecef": r_U, "v_ecef": v_U},
                   "receiver ECEF position (m) and Earth-relative velocity (m/s)"))
    r_S, v_S, a_S, r_rx = (ca.SX.sym(n, 3) for n in ("r_S_ecef", "v_S_ecef", "a_S_ecef", "r_rx_ecef"))
    r_tx, v_tx, tau = transmit_state(r_S, v_S, a_S, r_rx)
    out.append(_fn("leonav_transmit_state", {"r_S_ecef": r_S, "v_S_ecef": v_S, "a_S_ecef": a_S, "r_rx_ecef": r_rx},
                   {"r_tx_ecef": r_tx, "v_tx_ecef": v_tx, "tau_s": tau},
                   "satellite ECEF state at the transmit time of a signal received at r_rx (light time tau, s)"))
    out.append(_fn("leonav_level", {"f_b": f_b}, {"roll_pitch": frames.level_from_specific_force(f_b)},
                   "roll and pitch (rad) of a body at rest from its mean specific force (m/s^2, body FLU)"))
    sigma, span = ca.SX.sym("sigma_hz_s"), ca.SX.sym("f_b_span_s")
    out.append(_fn("leonav_doppler_rate_variance", {"sigma_hz_s": sigma, "f_b_span_s": span, "p": p},
                   {"R": input_noise.doppler_rate_variance(sigma, p[P_BLOCK["f_c_hz"].offset], p[P_BLOCK["vrw"].offset], span)},
                   "Doppler-rate variance (Hz^2/s^2): beacon noise sigma plus the accelerometer noise of "
                   "the specific force averaged over f_b_span_s (s) that enters the model"))
    dt_e = ca.SX.sym("dt")
    Phi_e, Qd_e = dynamics.error_step(dt_e, p)
    out.append(_fn("leonav_sensor_error_step", {"dt": dt_e, "p": p}, {"Phi": Phi_e, "Qd": Qd_e},
                   "transition and process noise (NDX x NDX) over dt of every block the mechanization does not "
                   "drive (zero on the 9D): what the simulator draws sensor-error truth with"))
    el, az, iono, tropo = gnss_code.delay_terms(x, aux, p)
    out.append(_fn("leonav_gnss_terms", {"x": x, "aux": aux, "p": p},
                   {"el_az_iono_tropo": ca.vertcat(el, az, iono, tropo)},
                   "GNSS signal at the receiver: elevation, azimuth (rad), ionosphere and troposphere "
                   "delays (m) as the GNSS pseudorange model adds them"))
    # consider treatment of ephemeris error: dh/d(satellite r, v in aux), after every other
    # function so the existing ones keep their place in the generated C
    for suffix in orbit_observables():
        out.append(_fn(f"leonav_orbit_jac_{suffix}", {"x": x, "aux": aux, "p": p},
                       {"J_orbit": orbit_jacobian(measurement_models()[suffix](x, aux, p), aux)},
                       f"{suffix}: 1 x 12 Jacobian dh/d[r_S, v_S, r_ref, v_ref] (ECEF, m and m/s) of the aux "
                       "satellite states (consider term R + J P_sat J^T)"))
    return out


def _update_functions(call, suffix: str, innovation_sx, joseph_fn: ca.Function, sx_in, mx_in) -> list[ca.Function]:
    """An observable's SX innovation (y, b = P H^T, S and nis = y^2 / S) and its update, the
    MX composition of it with the shared Joseph step. The update's C is plain glue over the
    two (codegen/emit_pipeline.py): an MX function copies its callee's x_post and P_post
    (553 doubles) through its work vector on every update."""
    names = ("x", "P", "z", "R", "aux", "p")
    y, b, S = innovation_sx
    innovation = _fn(f"leonav_innovation_{suffix}", dict(zip(names, sx_in)), {"y": y, "b": b, "S": S, "nis": y * y / S},
                     f"{suffix}: innovation y = z - h, b = P H^T, S = H b + R and nis = y^2 / S")
    innovation.internal = True   # called by leonav_update_<k> only
    ym, bm, Sm, nism = call(innovation)(*mx_in)
    x_post, P_post = call(joseph_fn)(mx_in[0], mx_in[1], ym, bm, Sm)
    update = _fn(f"leonav_update_{suffix}", dict(zip(names, mx_in)),
                 {"x_post": x_post, "P_post": P_post, "y": ym, "S": Sm, "nis": nism},
                 f"{suffix}: scalar Joseph-form update")
    # y and S are also the Joseph step's arguments: they pass through the work vector, since a
    # caller may leave those results NULL (not wanted)
    scalar = ca.Sparsity.dense(1, 1)
    update.pipeline = Pipeline(update, (
        Step(innovation, tuple(f"in:{n}" for n in names), ("tmp:y", "tmp:b", "tmp:S", "out:nis")),
        Step(joseph_fn, ("in:x", "in:P", "tmp:y", "tmp:b", "tmp:S"), ("out:x_post", "out:P_post")),
    ), {"y": ("y", scalar), "S": ("S", scalar)})
    return [innovation, update]


def _predict_functions(call, x, P, u, dt, p) -> list[ca.Function]:
    """The predict's three SX stages (models.ekf.nav_predict) and the MX `leonav_predict` over
    them. F and G pass between the stages with their structural sparsity, so the covariance
    stages compute on the same non-zeros, in the same order, as one SX function would."""
    x_next, F, G = ekf.nav_jacobians(x, u, dt, p)
    F, G = ca.sparsify(F), ca.sparsify(G)
    transition = _fn("leonav_predict_transition", {"x": x, "u": u, "dt": dt, "p": p},
                     {"x_next": x_next, "F": F, "G": G},
                     "predict stage 1: nominal step, error-state transition F and input Jacobian G "
                     "(structurally sparse)", dense=False)
    F_s, G_s = ca.SX.sym("F", F.sparsity()), ca.SX.sym("G", G.sparsity())
    M, Q_pre = ekf.predict_pre_covariance(P, F_s, G_s, dt, p)
    # symmetric: its lower triangle passes to the next stage (column-major, that is the upper
    # triangle's rows one after another: a part of this stage computes a block of F_pre P rows)
    M = ca.tril(M)
    pre = _fn("leonav_predict_pre_covariance", {"P": P, "F": F_s, "G": G_s, "dt": dt, "p": p},
              {"M": M, "Q_pre": Q_pre},
              "predict stage 2: pre-state covariance F_pre P F_pre^T + G_pre V G_pre^T and its IMU "
              "noise part (position trapezoid factored out)", dense=False)
    M_s, Q_s = ca.SX.sym("M", M.sparsity()), ca.SX.sym("Q_pre", Q_pre.sparsity())
    M_full = ekf.symmetric_from_upper(M.shape[0], lambda i, j: M_s[j, i])
    P_next, Qd = ekf.predict_project(M_full, Q_s, dt, p)
    project = _fn("leonav_predict_project", {"M": M_s, "Q_pre": Q_s, "dt": dt, "p": p},
                  {"P_next": P_next, "Qd": Qd},
                  "predict stage 3: P_next = T M T^T + Q_rw and Qd = T Q_pre T^T + Q_rw "
                  "(T the position trapezoid, Q_rw the bias, clock and LO random walks)")
    xm, Pm, um, dtm, pm = (ca.MX.sym(n, *v.shape) for n, v in (("x", x), ("P", P), ("u", u), ("dt", dt), ("p", p)))
    xn_m, F_m, G_m = call(transition)(xm, um, dtm, pm)
    M_m, Q_m = call(pre)(Pm, F_m, G_m, dtm, pm)
    P_m, Qd_m = call(project)(M_m, Q_m, dtm, pm)
    predict = _fn("leonav_predict", {"x": xm, "P": Pm, "u": um, "dt": dtm, "p": pm},
                  {"x_next": xn_m, "P_next": P_m, "F": F_m, "Qd": Qd_m},
                  "error-state EKF predict: P_next = F P F^T + Qd")
    for stage in (transition, pre, project):
        stage.internal = True   # called by leonav_predict only: sparse arguments, not a driver entry
    # the C of leonav_predict: plain glue over the stages (no copies; codegen/emit_pipeline.py)
    predict.pipeline = Pipeline(predict, (
        Step(transition, ("in:x", "in:u", "in:dt", "in:p"), ("out:x_next", "tmp:F", "tmp:G")),
        Step(pre, ("in:P", "tmp:F", "tmp:G", "in:dt", "in:p"), ("tmp:M", "tmp:Q_pre")),
        Step(project, ("tmp:M", "tmp:Q_pre", "in:dt", "in:p"), ("out:P_next", "out:Qd")),
    ), {"F": ("F", F.sparsity())})
    return [transition, pre, project, predict]
