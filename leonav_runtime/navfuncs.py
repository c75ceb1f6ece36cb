"""Generated model functions called one at a time from Python (no casadi import).

The simulator and the metrics need a few model quantities outside the filter loop: the
mechanization, measurement predictions with their Jacobians, boxplus/boxminus, and
quaternion <-> Euler conversion. They are all *generated* functions in the compiled
library; this module calls them through CasADi's C calling convention
(`f(arg, res, iw, w, mem)` with buffers sized by `f_work`), so no equation is written
twice. For the filter loop itself use `leonav_runtime.filter`.
"""
from __future__ import annotations

import ctypes
from typing import Sequence

import numpy as np

from leonav_runtime import compiled

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
        self._arg = (_dp * max(n_arg, self.n_in))()
        self._res = (_dp * max(n_res, self.n_out))()
        self._iw = np.zeros(max(n_iw, 1), dtype=np.intc)
        self._w = np.zeros(max(n_w, 1))

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
        keep = []
        for i, (value, (r, c)) in enumerate(zip(inputs, self.in_shapes)):
            arr = np.asarray(value, dtype=np.float64).reshape(-1, order="F")
            if arr.size != r * c:
                raise ValueError(f"{self.name}: input {i} has {arr.size} values, expected {r}x{c}")
            arr = np.ascontiguousarray(arr)
            keep.append(arr)
            self._arg[i] = arr.ctypes.data_as(_dp)
        outs = [np.zeros(r * c) for r, c in self.out_shapes]
        for i, arr in enumerate(outs):
            self._res[i] = arr.ctypes.data_as(_dp)
        rc = self._f(self._arg, self._res, self._iw.ctypes.data_as(_ip), self._w.ctypes.data_as(_dp), 0)
        if rc != 0:
            raise RuntimeError(f"{self.name} returned {rc}")
        return [o.reshape((r, c), order="F") for o, (r, c) in zip(outs, self.out_shapes)]


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
        self._q_from_euler = GeneratedFunction(lib, "leonav_q_from_euler")
        self._euler_from_q = GeneratedFunction(lib, "leonav_euler_from_q")
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

    def boxplus(self, x: np.ndarray, dx: np.ndarray) -> np.ndarray:
        """x [+] dx (attitude error is a body-frame rotation vector, rad)."""
        return self._boxplus(x, dx)[0][:, 0]

    def boxminus(self, x1: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """x1 [-] x0, row-wise for (n, NX) arrays; returns (n, NDX) or (NDX,)."""
        x1, x0 = np.atleast_2d(x1), np.atleast_2d(x0)
        out = np.array([self._boxminus(a, b)[0][:, 0] for a, b in zip(x1, x0)])
        return out if out.shape[0] > 1 or x1.ndim > 1 else out[0]

    def quat_from_euler(self, rpy: np.ndarray) -> np.ndarray:
        """q_nb [w x y z] from roll, pitch, yaw (rad), row-wise for (n, 3)."""
        rpy = np.atleast_2d(rpy)
        return np.array([self._q_from_euler(r)[0][:, 0] for r in rpy])

    def euler_from_quat(self, q: np.ndarray) -> np.ndarray:
        """roll, pitch, yaw (rad) of q_nb, row-wise for (n, 4)."""
        q = np.atleast_2d(q)
        return np.array([self._euler_from_q(v)[0][:, 0] for v in q])

    def imu_increments(self, x: np.ndarray, x_target: np.ndarray, dt: float,
                       guess: np.ndarray | None = None, tol: float = 1e-13) -> np.ndarray:
        """IMU increments u (6,) that take x to the velocity and attitude of x_target in dt.

        Newton iterations on the generated mechanization (finite-difference Jacobian), with
        the residual measured by the generated boxminus (velocity and attitude blocks).
        """
        L = self.layout
        sel = np.r_[L.DX_DV:L.DX_DV + 3, L.DX_DTHETA:L.DX_DTHETA + 3]

        def residual(u):
            return self._boxminus(self.mech(x, u, dt), x_target)[0][sel, 0]

        u = np.zeros(6) if guess is None else np.array(guess, dtype=float)
        step = 1e-7
        for _ in range(6):
            r0 = residual(u)
            if np.max(np.abs(r0)) < tol:
                break
            J = np.column_stack([(residual(u + step * e) - r0) / step for e in np.eye(6)])
            u = u - np.linalg.solve(J, r0)
        return u
