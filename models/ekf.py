"""Generic error-state EKF pieces, built from a nominal model by differentiation (CasADi SX).

Nothing in the generic part knows the navigation equations: the Jacobians of the nominal
transition f(x, u), the retraction boxplus/boxminus and a measurement h(x) are derived
symbolically:
    F = d[f(x [+] dx, u) [-] f(x, u)]/d dx at dx = 0
    G = d[f(x, u + du) [-] f(x, u)]/d du at du = 0   (maps input noise to the error state)
    H = d[h(x [+] dx)]/d dx at dx = 0
The covariance algebra is built on the structural non-zeros of F and H and on the symmetry
of P (`congruence`, `innovation`, `joseph_update`): it becomes straight-line C with no
work on zeros and each symmetric entry computed once.
The navigation instance (state layout, IMU noise, clock) is `nav_predict` / `nav_update`.
"""
from __future__ import annotations

from typing import Callable

import casadi as ca

from leonav.models import frames, kinematics
from leonav.models import dynamics
from leonav.models.state import DX, NDX, P, U, X

def _at_zero(expr, sym):
    return ca.substitute(expr, sym, ca.DM.zeros(sym.shape))


def _sym(shape_like: int, name: str):
    return ca.SX.sym(name, shape_like)


def error_jacobian(f: Callable, x, boxplus: Callable, boxminus: Callable, ndx: int):
    """d[f(x [+] dx) [-] f(x)]/d dx at dx = 0 for a state-to-state map f."""
    dx = _sym(ndx, "dx")
    return _at_zero(ca.jacobian(boxminus(f(boxplus(x, dx)), f(x)), dx), dx)


def input_jacobian(f: Callable, u, boxminus: Callable):
    """d[f(u + du) [-] f(u)]/d du at du = 0 for a map from the input to the state."""
    du = _sym(u.shape[0], "du")
    return _at_zero(ca.jacobian(boxminus(f(u + du), f(u)), du), du)


def measurement_jacobian(h: Callable, x, boxplus: Callable, ndx: int):
    """d h(x [+] dx)/d dx at dx = 0 (row vector)."""
    dx = _sym(ndx, "dx")
    return _at_zero(ca.jacobian(h(boxplus(x, dx)), dx), dx)


def symmetric_from_upper(rows: int, entry: Callable):
    """Symmetric SX matrix whose (i, j) = (j, i) entry is `entry(i, j)` for i <= j (each built once)."""
    M = ca.SX(rows, rows)
    for j in range(rows):
        for i in range(j + 1):
            v = entry(i, j)
            if v.nnz() and not v.is_zero():  # keep structural zeros (of Qd, say) out of the pattern
                M[i, j] = v
                M[j, i] = v
    return M


def congruence(A, S):
    """A S A^T for a symmetric SX S, built on the structural non-zeros of A, upper triangle mirrored.

    B = A S costs nnz(A) x n products (rows of A that are unit vectors cost nothing);
    then only the n (n + 1) / 2 entries B[i, :] A[j, :]^T with i <= j are formed.
    """
    B = ca.mtimes(A, S)
    return symmetric_from_upper(A.shape[0], lambda i, j: ca.dot(B[i, :], A[j, :]))


def upper_mirrored(P_):
    """P's upper triangle mirrored (SX): the symmetric matrix a step works on, read as LAPACK's
    uplo = 'U' reads one. A covariance the filter keeps is exactly symmetric (every step writes
    both triangles from one expression), so this equals (P + P^T) / 2 bit for bit, without its
    n (n - 1) / 2 additions and halvings and with half the loads; the lower triangle is never
    read. A caller's non-symmetric P is symmetrized once where it enters (`EKF`, `pcrb`)."""
    return symmetric_from_upper(P_.shape[0], lambda i, j: P_[i, j])


def innovation(P_, z, R, h_pred, H):
    """(y, b, S) of a scalar measurement: y = z - h_pred, b = P H^T, S = H b + R (SX).

    b is formed from P's upper triangle (`upper_mirrored`) over H's structural non-zero columns only.
    """
    b = ca.mtimes(upper_mirrored(P_), H.T)
    return z - h_pred, b, ca.mtimes(H, b) + R


def joseph_update(x, P_, y, b, S, boxplus: Callable):
    """(x_post, P_post) of a scalar update from its innovation y, b = P H^T and S (SX).

    K = b / S, x_post = x [+] K y, and the Joseph form (I - K H) P (I - K H)^T + K R K^T
    evaluated expanded, P - K b^T - b K^T + S K K^T = P - K c^T - c K^T with
    c = b - S K / 2: an identity for any gain K (so it keeps the Joseph form's tolerance
    of gain errors) that costs O(n^2), not O(n^3). P is read from its upper triangle
    (`upper_mirrored`) and only the upper triangle of the result is formed (then mirrored).
    """
    K = b / S
    c = b - S * K / 2
    P_sym = upper_mirrored(P_)
    P_post = symmetric_from_upper(P_.shape[0], lambda i, j: P_sym[i, j] - (K[i] * c[j] + c[i] * K[j]))
    return boxplus(x, K * y), P_post


def scalar_update(x, P_, z, R, h_pred, H, boxplus: Callable):
    """One scalar measurement update, Joseph form, from the prediction h_pred and its H (1 x n), SX.

    Returns (x_post, P_post, y, S, nis) with y = z - h_pred, S = H P H^T + R,
    K = P H^T / S, P_post = (I - K H) P (I - K H)^T + K R K^T (Joseph), x_post = x [+] K y,
    nis = y^2 / S (see `innovation` and `joseph_update`).
    The attitude covariance is not rotated by the reset (the reset Jacobian
    I - [K y]_theta x / 2 differs from I by the size of the attitude correction).
    """
    y, b, S = innovation(P_, z, R, h_pred, H)
    x_post, P_post = joseph_update(x, P_, y, b, S, boxplus)
    return x_post, P_post, y, S, y * y / S


def information_add(J, H, R):
    """Fisher information after a scalar measurement: J + H^T H / R."""
    return J + ca.mtimes(H.T, H) / R


def information_step(B, H, R):
    """(B_next, S): the PCRB's scalar measurement step on the bound B = J^-1.

    `information_add` written on B by Sherman-Morrison, so no matrix is inverted:
    (J + H^T H / R)^-1 = B - b b^T / S with b = B H^T, S = R + H b.
    It is the Joseph update with the optimal gain K = b / S (tests check both). B is a
    symmetric bound (the prior, F B F^T + Qd and this step keep it exactly symmetric:
    b_i b_j = b_j b_i). Dense products, for MX: the generated code is three small loops
    (b, S accumulated from R, then B - (b_i b_j) / S) in the order of the hand-written
    driver loop it replaced, so the bound is reproduced to the bit. H (1 x n) is an input,
    so one generated function serves every observable.
    """
    b = ca.mtimes(B, H.T)
    S = ca.mac(H, b, R)
    return B - ca.mtimes(b, b.T) / S, S


# --- navigation instance ---------------------------------------------------------------

def imu_noise_variance(dt, p):
    """Variances (NU) of the IMU increments over dt: arw^2 dt (dtheta_b), vrw^2 dt (dvel_b)."""
    return ca.vertcat(
        ca.repmat(p[P["arw"].offset] ** 2 * dt, U["dtheta_b"].size, 1),
        ca.repmat(p[P["vrw"].offset] ** 2 * dt, U["dvel_b"].size, 1),
    )


def imu_process_noise(G, dt, p):
    """G diag(imu_noise_variance) G^T (symmetric by construction), G mapping the increments to a state."""
    GV = G @ ca.diag(imu_noise_variance(dt, p))
    return symmetric_from_upper(G.shape[0], lambda i, j: ca.dot(GV[i, :], G[j, :]))


def random_walk_noise(dt, p):
    """Discrete noise (NDX x NDX) of every block the mechanization does not drive (biases,
    clock, LO offset, inter-system biases, each sensor's own): `models.dynamics.process_noise`,
    from each block's registry dynamics."""
    return dynamics.process_noise(dt, p)


def nav_process_noise(G, dt, p):
    """Discrete process noise Qd (NDX x NDX) of the navigation error state over dt.

    IMU white noise enters through the increments: Cov(dtheta_b) = arw^2 dt I,
    Cov(dvel_b) = vrw^2 dt I, mapped by G = d(mech [-] mech)/du (NDX x NU, obtained by
    differentiation), so Qd_imu = G diag(...) G^T (first order, noise injected at
    the increment), plus `random_walk_noise`.
    """
    return imu_process_noise(G, dt, p) + random_walk_noise(dt, p)


class FirstOrderReplay:
    """A costly sub-model (gravity) replaced by its first-order expansion inside a Jacobian.

    `record(v, p)` evaluates f(v) and df/dv at the nominal argument and stores them;
    `replay()` returns a function that, on its k-th call, gives f_k + J_k (v - v_k). That
    has the same value and first derivative as f at the recorded points, so a Jacobian
    taken at the nominal point is unchanged, but f is differentiated once per evaluation
    point (3 directions) instead of once per direction of the outer Jacobian.
    """

    def __init__(self, f: Callable):
        self.f, self.points = f, []

    def record(self, v, p):
        s = ca.SX.sym("v", v.shape[0])
        f_s = self.f(s, p)
        f_v, J_v = ca.substitute([f_s, ca.jacobian(f_s, s)], [s], [v])
        self.points.append((v, f_v, J_v))
        return f_v

    def replay(self) -> Callable:
        """A stand-in for f whose k-th call expands around the k-th recorded point (same call order)."""
        calls = iter(self.points)
        def first_order(v, p):
            try:
                v_k, f_k, J_k = next(calls)
            except StopIteration:
                raise RuntimeError("FirstOrderReplay: more calls than recorded points") from None
            return f_k + J_k @ (v - v_k)
        return first_order


def nav_jacobians(x, u, dt, p):
    """(x_next, F, G): nominal step, error-state transition and input Jacobians (SX).

    mech(x, u) = core(x, w(x, u)) with w the bias-corrected increments, and the biases reach
    the core only through w. So by the chain rule
        F = d core/d dx |_w + (d core/d w) (d w/d dx),   G = (d core/d w) (d w/d du):
    the bias columns of F come from the 6-column input Jacobian that Qd needs anyway,
    instead of 6 more directions differentiated through the whole mechanization.
    Gravity enters the Jacobians through its recorded first-order expansion (FirstOrderReplay).
    """
    w = kinematics.corrected_increments(x, u, dt)
    gravity = FirstOrderReplay(kinematics.gravity_enu)
    x_next = kinematics.mech_corrected(x, w, dt, p, gravity.record)
    def core(xx, ww):
        return kinematics.mech_corrected(xx, ww, dt, p, gravity.replay())
    F_x = error_jacobian(lambda xx: core(xx, w), x, frames.boxplus, frames.boxminus, NDX)
    G_w = input_jacobian(lambda ww: core(x, ww), w, frames.boxminus)
    dw_dx = measurement_jacobian(lambda xx: kinematics.corrected_increments(xx, u, dt), x, frames.boxplus, NDX)
    dw_du = ca.jacobian(kinematics.corrected_increments(x, u, dt), u)
    return x_next, F_x + G_w @ dw_dx, G_w @ dw_du


def nav_transition(x, u, dt, p):
    """(x_next, F, Qd) of the navigation model over one IMU interval (SX)."""
    x_next, F, G = nav_jacobians(x, u, dt, p)
    return x_next, F, nav_process_noise(G, dt, p)


_PRE_SIZES = ("dv", "dtheta", "dp", "dv")   # pre-state blocks before the rest (see trapezoid_factors)


def trapezoid_pre(F, G):
    """(F_pre, G_pre): the Jacobians of the pre-state of the position trapezoid (trapezoid_factors)."""
    dp, dv, dth = DX["dp"].slice, DX["dv"].slice, DX["dtheta"].slice
    rest = slice(DX["db_a"].offset, NDX)
    E = ca.SX.eye(NDX)
    F_pre = ca.vertcat(F[dv, :], F[dth, :], E[dp, :], E[dv, :], F[rest, :])
    n_pv = DX["dp"].size + DX["dv"].size
    G_pre = ca.vertcat(G[dv, :], G[dth, :], ca.SX(n_pv, G.shape[1]), G[rest, :])
    return F_pre, G_pre


def trapezoid_map(dt):
    """T: the sparse, linear map from the trapezoid's pre-state to dx+ (trapezoid_factors)."""
    n_rest = NDX - DX["db_a"].offset
    sizes = tuple(DX[name].size for name in _PRE_SIZES)
    s = ca.SX.sym("s", sum(sizes) + n_rest)
    ends = [sum(sizes[: k + 1]) for k in range(len(sizes))]
    v_next, th_next, pos, vel = (s[e - n : e] for e, n in zip(ends, sizes))
    image = ca.vertcat(kinematics.trapezoid_position(pos, vel, v_next, dt), v_next, th_next, s[ends[-1] :])
    return ca.jacobian(image, s)


def trapezoid_factors(F, G, dt):
    """(T, F_pre, G_pre) with F = T F_pre and G = T G_pre, from the position trapezoid.

    The mechanization ends with p+ = p + (v + v+) dt / 2 (kinematics.trapezoid_position), so
    the dp rows of F and G are combinations of the dv rows. The pre-state of that last step,
    [dv+, dtheta+, dp, dv, db_a, db_g, dc_dt, dc_ddt, db_lo, ...] (the dense rows first),
    has the Jacobian F_pre (F's dv, dtheta and later rows, unit rows for dp and dv) and T
    (its sparse, linear map to dx+) is the Jacobian of that step, so the expensive product
    F_pre P F_pre^T has 3 fewer dense rows. tests/test_models_jacobians checks T F_pre = F.
    """
    return (trapezoid_map(dt), *trapezoid_pre(F, G))


def predict_pre_covariance(P_, F, G, dt, p):
    """(M, Q_pre): the pre-state covariance F_pre P F_pre^T + G_pre V G_pre^T (symmetric, upper
    triangle mirrored) and its IMU noise part Q_pre = G_pre V G_pre^T (SX; nav_predict)."""
    F_pre, G_pre = trapezoid_pre(F, G)
    Q_pre = imu_process_noise(G_pre, dt, p)
    B_pre = congruence(F_pre, upper_mirrored(P_))
    return symmetric_from_upper(B_pre.shape[0], lambda i, j: B_pre[i, j] + Q_pre[i, j]), Q_pre


def predict_project(M, Q_pre, dt, p):
    """(P_next, Qd) = (T M T^T + Q_rw, T Q_pre T^T + Q_rw) from the pre-state covariances (SX; nav_predict)."""
    T = trapezoid_map(dt)
    Q_rw = random_walk_noise(dt, p)
    return congruence(T, M) + Q_rw, congruence(T, Q_pre) + Q_rw


def nav_predict(x, P_, u, dt, p):
    """(x_next, P_next, F, Qd) of the navigation filter over one IMU interval (SX).

    P_next = F P F^T + Qd computed as T (F_pre P F_pre^T + G_pre V G_pre^T) T^T + Q_rw
    (trapezoid_factors; V the IMU increment variances, Q_rw = random_walk_noise), upper
    triangles only, on the structural non-zeros (`congruence`). The generated predict runs
    the same three stages as separate functions (nav_jacobians, predict_pre_covariance,
    predict_project): each stage's C stays a reviewable size, the values are the same.
    """
    x_next, F, G = nav_jacobians(x, u, dt, p)
    M, Q_pre = predict_pre_covariance(P_, F, G, dt, p)
    P_next, Qd = predict_project(M, Q_pre, dt, p)
    return x_next, P_next, F, Qd


def cv_step(x, dt, p):
    """Nominal constant-velocity step over dt (s), the motion model of a receiver without IMU:
    p_enu += v_enu dt, velocity and attitude held, every other block by its own dynamics
    (`models.dynamics.block_step`: c_dt += c_ddt dt, random walks held)."""
    pos, vel, q = X["p_enu"].slice, X["v_enu"].slice, X["q_nb"].slice
    return ca.vertcat(x[pos] + x[vel] * dt, x[vel], x[q], *dynamics.block_step(x, dt, p))


def cv_process_noise(dt, p):
    """Discrete process noise (NDX x NDX) of the constant-velocity model over dt.

    White acceleration of PSD q = vrw^2 (m^2/s^3; the parameter `vrw` is the velocity random
    walk of the receiver's motion, as it is for an IMU's accelerometer noise) on each ENU
    axis: q dt^3/3 (dp), q dt^2/2 (dp dv), q dt (dv); plus `random_walk_noise` (clock, LO
    offset; the IMU bias walks, which nothing observes without an IMU). Attitude: none.
    """
    q = p[P["vrw"].offset] ** 2
    Q = random_walk_noise(dt, p)
    for k in range(DX["dp"].size):
        i, j = DX["dp"].offset + k, DX["dv"].offset + k
        Q[i, i] += q * dt**3 / 3
        Q[i, j] += q * dt**2 / 2
        Q[j, i] += q * dt**2 / 2
        Q[j, j] += q * dt
    return Q


def cv_predict(x, P_, dt, p):
    """(x_next, P_next, F, Qd) of the constant-velocity model over dt (SX).

    F = d[cv_step(x [+] dx) [-] cv_step(x)]/d dx (identity plus the dt couplings p <- v and
    c_dt <- c_ddt), P_next = F P F^T + Qd on F's structural non-zeros (`congruence`).
    """
    x_next = cv_step(x, dt, p)
    F = error_jacobian(lambda xx: cv_step(xx, dt, p), x, frames.boxplus, frames.boxminus, NDX)
    Qd = cv_process_noise(dt, p)
    FPF = congruence(F, upper_mirrored(P_))
    P_next = symmetric_from_upper(NDX, lambda i, j: FPF[i, j] + Qd[i, j])
    return x_next, P_next, F, Qd


def nav_h(h: Callable, x, aux, p):
    """(prediction, H) of a navigation observable h(x, aux, p) (SX)."""
    hx = lambda xx: h(xx, aux, p)  # noqa: E731
    return hx(x), measurement_jacobian(hx, x, frames.boxplus, NDX)


def nav_update(h: Callable, x, P_, z, R, aux, p):
    """Scalar update of the navigation filter with measurement model h(x, aux, p) (SX)."""
    h_pred, H = nav_h(h, x, aux, p)
    return scalar_update(x, P_, z, R, h_pred, H, frames.boxplus)

