"""Generated model functions called one at a time from Python (no casadi import).

The simulator and the metrics need a few model quantities outside the filter loop: the
mechanization, measurement predictions with their Jacobians, boxplus/boxminus, and
quaternion <-> Euler conversion. They are all *generated* functions in the compiled
library; this module calls them through CasADi's C calling convention
(`f(arg, res, iw, w, mem)` with buffers sized by `f_work`), so no equation is written
twice. For the filter loop itself use `leonav_runtime.core.filter`.

Thread safety: a GeneratedFunction (and NavFunctions.boxminus) owns one set of buffers and
serializes its calls with a lock, so one NavFunctions can be shared by threads (a Dask
worker runs trials in threads and shares the process's prepared scenario); without it,
concurrent calls overwrote each other's inputs.
"""
from __future__ import annotations

import ctypes
import threading
from typing import Sequence

import numpy as np

from leonav_runtime.core import compiled

_dp = ctypes.POINTER(ctypes.c_double)
_ip = ctypes.POINTER(ctypes.c_int)


class GeneratedFunction:
    """One generated function, called with NumPy inputs; returns dense NumPy outputs.

    Inputs are flattened column-major (CasADi's order); outputs are returned with the
    shapes of the function's output sparsity (column-major reshaped).
    """

    def __init__(self, lib: ctypes.CDLL, name: str) -> None:
        self.name = name
        self._f = getattr(lib, name)
        self._f.restype = ctypes.c_int
        self._f.argtypes = [ctypes.POINTER(_dp), ctypes.POINTER(_dp), _ip, _dp, ctypes.c_int]
        sz = [ctypes.c_int() for _ in range(4)]
        work = getattr(lib, f"{name}_work")
        work.restype = ctypes.c_int
        work(*(ctypes.byref(s) for s in sz))
        n_arg, n_res, n_iw, n_w = (s.value for s in sz)
        n_in = getattr(lib, f"{name}_n_in")
        n_out = getattr(lib, f"{name}_n_out")
        n_in.restype = n_out.restype = ctypes.c_int
        self.n_in, self.n_out = n_in(), n_out()
        self.in_shapes = [self._shape(lib, f"{name}_sparsity_in", i) for i in range(self.n_in)]
        self.out_shapes = [self._shape(lib, f"{name}_sparsity_out", i) for i in range(self.n_out)]
        # Buffers and pointer tables are made once: a call only copies values in and out.
        self._in = [np.zeros(r * c) for r, c in self.in_shapes]
        self._out = [np.zeros(r * c) for r, c in self.out_shapes]
        self._arg = (_dp * max(n_arg, self.n_in))(*(b.ctypes.data_as(_dp) for b in self._in))
        self._res = (_dp * max(n_res, self.n_out))(*(b.ctypes.data_as(_dp) for b in self._out))
        self._iw = np.zeros(max(n_iw, 1), dtype=np.intc)
        self._w = np.zeros(max(n_w, 1))
        self._iw_p, self._w_p = self._iw.ctypes.data_as(_ip), self._w.ctypes.data_as(_dp)
        self._lock = threading.Lock()  # the buffers above are shared by every call

    @staticmethod
    def _shape(lib, fname: str, i: int) -> tuple[int, int]:
        fn = getattr(lib, fname)
        fn.restype = ctypes.POINTER(ctypes.c_int)
        fn.argtypes = [ctypes.c_int]
        sp = fn(i)
        return int(sp[0]), int(sp[1])

    def __call__(self, *inputs: Sequence[float] | float) -> list[np.ndarray]:
        if len(inputs) != self.n_in:
            raise TypeError(f"{self.name}: expected {self.n_in} inputs, got {len(inputs)}")
        arrays = [np.asarray(value, dtype=np.float64) for value in inputs]
        for i, (arr, buf) in enumerate(zip(arrays, self._in)):
            if arr.size != buf.size:
                r, c = self.in_shapes[i]
                raise ValueError(f"{self.name}: input {i} has {arr.size} values, expected {r}x{c}")
        with self._lock:
            for arr, buf in zip(arrays, self._in):
                buf[:] = arr.ravel(order="F")
            rc = self._f(self._arg, self._res, self._iw_p, self._w_p, 0)
            if rc != 0:
                raise RuntimeError(f"{self.name} returned {rc}")
            return [o.reshape((r, c), order="F").copy() for o, (r, c) in zip(self._out, self.out_shapes)]


class NavFunctions:
    """The generated model functions the simulator and metrics use (SI units, frames as
    in docs/design.md). `params` is the parameter vector (NP,)."""

    def __init__(self, params: np.ndarray | None = None, library: compiled.Library | None = None) -> None:
        self.library = library if library is not None else compiled.load()
        self.layout = self.library.layout
        self.params = None if params is None else np.asarray(params, dtype=np.float64)
        lib = self.library.lib
        self._mech = GeneratedFunction(lib, "leonav_mech")
        self._boxplus = GeneratedFunction(lib, "leonav_boxplus")
        self._boxminus = GeneratedFunction(lib, "leonav_boxminus")
        self._work = None
        self._work_lock = threading.Lock()  # one workspace for boxminus, shared by threads
        self._q_from_euler = GeneratedFunction(lib, "leonav_q_from_euler")
        self._euler_from_q = GeneratedFunction(lib, "leonav_euler_from_q")
        self._gravity = GeneratedFunction(lib, "leonav_gravity_enu")
        self._transmit = GeneratedFunction(lib, "leonav_transmit_state")
        self._receiver_ecef = GeneratedFunction(lib, "leonav_receiver_ecef")
        self._level = GeneratedFunction(lib, "leonav_level")
        self._dr_variance = GeneratedFunction(lib, "leonav_doppler_rate_variance")
        self._error_step = GeneratedFunction(lib, "leonav_sensor_error_step")
        self._h = {kid: GeneratedFunction(lib, f"leonav_h_{name}")
                   for name, kid in self.library.meas_ids.items()}

    def kind_id(self, kind: int | str) -> int:
        return self.library.kind_id(kind)

    def mech(self, x: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray:
        """Nominal state after one IMU interval dt (s) with increments u (rad, m/s)."""
        return self._mech(x, u, dt, self.params)[0][:, 0]

    def h(self, kind: int | str, x: np.ndarray, aux: np.ndarray) -> tuple[float, np.ndarray]:
        """Predicted measurement and its Jacobian (NDX,) w.r.t. the error state."""
        h, H = self._h[self.kind_id(kind)](x, aux, self.params)
        return float(h[0, 0]), H[0]

    def doppler_rate_variance(self, sigma_hz_s, f_b_span_s: float, params: np.ndarray | None = None):
        """Variance (Hz^2/s^2) of a Doppler-rate record: the beacon's own noise `sigma_hz_s`
        plus the accelerometer noise (VRW of `params`) of the specific force averaged over
        `f_b_span_s` (s) that the model uses, at the carrier of `params` (default: self.params).
        A scalar or an array of sigmas (then an array of variances)."""
        p = self.params if params is None else params
        if np.ndim(sigma_hz_s) == 0:
            return float(self._dr_variance(sigma_hz_s, f_b_span_s, p)[0][0, 0])
        return np.array([self._dr_variance(s, f_b_span_s, p)[0][0, 0] for s in np.ravel(sigma_hz_s)]
                        ).reshape(np.shape(sigma_hz_s))

    def sensor_error_step(self, dt: float, params: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(Phi, Qd), NDX x NDX: transition and process noise over dt (s) of every block the
        mechanization does not drive (zero on the 9D), from the generated model."""
        Phi, Qd = self._error_step(dt, self.params if params is None else params)
        return Phi, Qd

    def _workspace(self):
        if self._work is None:
            self._work = self.library.new_workspace()
        return self._work

    def _rows(self, what: str, x_rows: np.ndarray, aux_rows: np.ndarray, params: np.ndarray | None):
        """(n, x (n, NX), aux (n, NAUX), p) as contiguous float64 for a batched driver call; one
        (NX,) state is used for every aux row."""
        L = self.layout
        aux = np.ascontiguousarray(np.atleast_2d(aux_rows), dtype=np.float64)
        n = aux.shape[0]
        x = np.asarray(x_rows, dtype=np.float64)
        x = np.ascontiguousarray(np.broadcast_to(x, (n, L.NX)) if x.ndim == 1 else x)
        if x.shape != (n, L.NX) or aux.shape[1] != L.NAUX:
            raise ValueError(f"{what}: expected x ({n}, {L.NX}) and aux ({n}, {L.NAUX}), got {x.shape}, {aux.shape}")
        p = np.ascontiguousarray(self.params if params is None else params, dtype=np.float64)
        return n, x, aux, p

    def h_many(self, kind: int | str, x_rows: np.ndarray, aux_rows: np.ndarray, params: np.ndarray | None = None,
               jacobian: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """Predictions (n,) and Jacobians (n, NDX) of observable `kind` for n rows, each with its
        own state (x_rows (n, NX), or one (NX,) state for every row) and aux (n, NAUX); one
        call into the driver's loop over the generated `leonav_h_<kind>`. A row whose result is
        not finite gets NaN."""
        L = self.layout
        n, x, aux, p = self._rows("h_many", x_rows, aux_rows, params)
        h = np.empty(n)
        H = np.empty((n, L.NDX)) if jacobian else None
        with self._work_lock:
            rc = self.library.lib.leonav_h_many(self.kind_id(kind), n, x.ctypes.data_as(_dp), aux.ctypes.data_as(_dp),
                                                p.ctypes.data_as(_dp), h.ctypes.data_as(_dp),
                                                None if H is None else H.ctypes.data_as(_dp), None,
                                                self._workspace().ctypes.data)
        if rc != L.OK:
            raise RuntimeError(f"leonav_h_many returned {compiled.code_name(rc, L)}")
        return h, H

    def orbit_jacobian_many(self, kind: int | str, x_rows: np.ndarray, aux_rows: np.ndarray,
                            params: np.ndarray | None = None) -> np.ndarray:
        """(n, NORBIT) dh/d[r_S, v_S, r_ref, v_ref] (unit of z per m and per m/s, ECEF) of
        observable `kind` at n rows (generated leonav_orbit_jac_<kind>, one driver call);
        x_rows (n, NX) or one (NX,) state, aux (n, NAUX). NaN rows where not finite."""
        L = self.layout
        n, x, aux, p = self._rows("orbit_jacobian_many", x_rows, aux_rows, params)
        J = np.empty((n, L.NORBIT))
        with self._work_lock:
            rc = self.library.lib.leonav_orbit_jacobian_many(self.kind_id(kind), n, x.ctypes.data_as(_dp),
                                                             aux.ctypes.data_as(_dp), p.ctypes.data_as(_dp),
                                                             J.ctypes.data_as(_dp), self._workspace().ctypes.data)
        if rc != L.OK:
            raise RuntimeError(f"leonav_orbit_jacobian_many returned {compiled.code_name(rc, L)}")
        return J

    def gnss_terms(self, x_rows: np.ndarray, aux_rows: np.ndarray, params: np.ndarray | None = None) -> np.ndarray:
        """(n, 4) [elevation (rad), azimuth (rad), ionosphere (m), troposphere (m)] of n GNSS
        signals (generated leonav_gnss_terms: the terms of the GNSS pseudorange model), one call;
        x_rows (n, NX) or one (NX,) state, aux (n, NAUX)."""
        L = self.layout
        n, x, aux, p = self._rows("gnss_terms", x_rows, aux_rows, params)
        out = np.empty((n, 4))
        with self._work_lock:
            rc = self.library.lib.leonav_gnss_terms_many(n, x.ctypes.data_as(_dp), aux.ctypes.data_as(_dp),
                                                         p.ctypes.data_as(_dp), out.ctypes.data_as(_dp),
                                                         self._workspace().ctypes.data)
        if rc != L.OK:
            raise RuntimeError(f"leonav_gnss_terms_many returned {compiled.code_name(rc, L)}")
        return out

    def boxplus_many(self, x_rows: np.ndarray, dx_rows: np.ndarray) -> np.ndarray:
        """x [+] dx row-wise for (n, NX) states and (n, NDX) errors (one call into the driver)."""
        L = self.layout
        x = np.ascontiguousarray(np.atleast_2d(x_rows), dtype=np.float64)
        dx = np.ascontiguousarray(np.atleast_2d(dx_rows), dtype=np.float64)
        if x.shape[1] != L.NX or dx.shape != (x.shape[0], L.NDX):
            raise ValueError(f"boxplus_many: expected (n, {L.NX}) and (n, {L.NDX}), got {x.shape}, {dx.shape}")
        out = np.empty_like(x)
        with self._work_lock:
            rc = self.library.lib.leonav_boxplus_many(x.shape[0], x.ctypes.data_as(_dp), dx.ctypes.data_as(_dp),
                                                      out.ctypes.data_as(_dp), self._workspace().ctypes.data)
        if rc != L.OK:
            raise RuntimeError(f"leonav_boxplus_many returned {compiled.code_name(rc, L)}")
        return out

    def receiver_ecef(self, x: np.ndarray, params: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Receiver ECEF position (m) and Earth-relative velocity (m/s) of state x."""
        r, v = self._receiver_ecef(x, self.params if params is None else params)
        return r[:, 0], v[:, 0]

    def gravity_enu(self, p_enu: np.ndarray, params: np.ndarray | None = None) -> np.ndarray:
        """Normal gravity vector (m/s^2, origin ENU axes) at p_enu (m)."""
        return self._gravity(p_enu, self.params if params is None else params)[0][:, 0]

    def transmit_state(self, r_S_ecef: np.ndarray, v_S_ecef: np.ndarray, a_S_ecef: np.ndarray,
                       r_rx_ecef: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """Satellite position (m) and velocity (m/s) at the transmit time of a signal received
        at r_rx_ecef, in the ECEF frame of the transmit epoch, and the light time (s)."""
        r_tx, v_tx, tau = self._transmit(r_S_ecef, v_S_ecef, a_S_ecef, r_rx_ecef)
        return r_tx[:, 0], v_tx[:, 0], float(tau[0, 0])

    def level(self, f_b: np.ndarray) -> tuple[float, float]:
        """Roll and pitch (rad) of a body at rest from its mean specific force (m/s^2, body FLU)."""
        rp = self._level(f_b)[0][:, 0]
        return float(rp[0]), float(rp[1])

    def boxplus(self, x: np.ndarray, dx: np.ndarray) -> np.ndarray:
        """x [+] dx (attitude error is a body-frame rotation vector, rad)."""
        return self._boxplus(x, dx)[0][:, 0]

    def boxminus(self, x1: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """x1 [-] x0 for (NX,) states -> (NDX,), or row-wise for (n, NX) arrays -> (n, NDX)
        (one call into the driver's loop over the generated boxminus)."""
        single = np.ndim(x1) == 1
        a = np.ascontiguousarray(np.atleast_2d(x1), dtype=np.float64)
        b = np.ascontiguousarray(np.atleast_2d(x0), dtype=np.float64)
        if a.shape != b.shape or a.shape[1] != self.layout.NX:
            raise ValueError(f"boxminus: expected two (n, {self.layout.NX}) arrays, got {a.shape} and {b.shape}")
        out = np.empty((a.shape[0], self.layout.NDX))
        with self._work_lock:
            rc = self.library.lib.leonav_boxminus_many(a.shape[0], a.ctypes.data_as(_dp), b.ctypes.data_as(_dp),
                                                      out.ctypes.data_as(_dp), self._workspace().ctypes.data)
        if rc != self.layout.OK:
            raise RuntimeError(f"leonav_boxminus_many returned {compiled.code_name(rc, self.layout)}")
        return out[0] if single else out

    def quat_from_euler(self, rpy: np.ndarray) -> np.ndarray:
        """q_nb [w x y z] from roll, pitch, yaw (rad), row-wise for (n, 3)."""
        rpy = np.atleast_2d(rpy)
        return np.array([self._q_from_euler(r)[0][:, 0] for r in rpy])

    def euler_from_quat(self, q: np.ndarray) -> np.ndarray:
        """roll, pitch, yaw (rad) of q_nb, row-wise for (n, 4)."""
        q = np.atleast_2d(q)
        return np.array([self._euler_from_q(v)[0][:, 0] for v in q])

    def imu_increments(self, x: np.ndarray, x_target: np.ndarray, dt: float,
                       guess: np.ndarray | None = None, jacobian: np.ndarray | None = None,
                       tol: float = 1e-13) -> tuple[np.ndarray, np.ndarray]:
        """IMU increments u (NU,) that take x to the velocity and attitude of x_target in dt.

        Newton iterations on the generated mechanization, the residual measured by the
        generated boxminus (velocity and attitude blocks). The finite-difference Jacobian is
        returned and can be passed back for the next interval (it changes slowly along a
        trajectory): it is only recomputed when the iteration does not converge with it.
        Returns (u, jacobian).
        """
        L = self.layout
        sel = np.r_[L.DX_DV_SLICE, L.DX_DTHETA_SLICE]

        def residual(u):
            return self._boxminus(self.mech(x, u, dt), x_target)[0][sel, 0]

        def fd_jacobian(u, r0, step=1e-7):
            return np.column_stack([(residual(u + step * e) - r0) / step for e in np.eye(L.NU)])

        u = np.zeros(L.NU) if guess is None else np.array(guess, dtype=float)
        J = jacobian
        r = residual(u)
        for iteration in range(12):
            if np.max(np.abs(r)) < tol:
                return u, J
            if J is None or iteration in (3, 7):  # chord iterations stalled: refresh the Jacobian
                J = fd_jacobian(u, r)
            u = u - np.linalg.solve(J, r)
            r = residual(u)
        if np.max(np.abs(r)) > 1e-9:
            raise RuntimeError(f"imu_increments did not converge (residual {np.max(np.abs(r)):.2e})")
        return u, J
