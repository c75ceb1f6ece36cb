"""Sensor tables: what every source (simulation, a recorded session, a dataset, live
devices) hands to the road into the filter.

One table per sensor kind. Times are float seconds since the source's epoch (one time
axis per run); SI units; frames in the field names: ENU at the run's origin (`_enu`),
Earth-fixed (`_ecef`), body forward-left-up (`_b`). `check()` raises one
`UserInputError` naming the table, the field and what was expected; `inputs.assemble`
checks every table it is given.
"""
from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.core import model
from leonav_runtime.gen import state_layout as LAYOUT


def _bad(table: str, name: str, problem: str, expected: str) -> UserInputError:
    return UserInputError(f"{table}: {name}: {problem}: expected {expected}")


def check_column(table: str, name: str, values, shape: tuple, finite: bool = True, positive: bool = False,
                 unit: str = "") -> None:
    """Raise a UserInputError unless `values` has `shape` (and is finite / > 0 as asked)."""
    arr = values if isinstance(values, np.ndarray) else np.asarray(values)
    # fast path: a sum is finite only if every value is (an overflow to inf goes the slow way and passes)
    if arr.shape == shape and (not arr.size or ((not finite or math.isfinite(arr.sum()))
                                                and (not positive or arr.min() > 0))):
        return
    if arr.shape != shape:
        raise _bad(table, name, f"shape {arr.shape}", f"shape {shape}")
    for wanted, test, problem, expected in ((finite, np.isfinite, "non-finite value", "finite"),
                                            (positive, _positive, "value <= 0", "positive")):
        good = test(arr) if wanted else None
        if wanted and not good.all():
            row = int(np.flatnonzero(~good.reshape(arr.shape[0] if arr.ndim else 1, -1).all(axis=1))[0])
            raise _bad(table, name, f"{problem} in row {row}", f"{expected} numbers{f' ({unit})' if unit else ''}")


def _positive(arr: np.ndarray) -> np.ndarray:
    return arr > 0


@dataclasses.dataclass
class ImuTable:
    """IMU intervals: t (n,) s, the end of each interval (the sample time); dt (n,) s > 0,
    its length; u (n, 6) the increments over (t - dt, t] in the generated input layout
    (`U_DTHETA_B_SLICE`: angle, rad; `U_DVEL_B_SLICE`: velocity, m/s; body FLU);
    rpy_rad (n, 3) or None, the sensor's own roll/pitch/yaw output (Z-Y-X, its own yaw
    reference) at the same samples.

    A sensor that reports rates enters through `from_rates`, which keeps them: `w_b_radps`
    and `f_b_mps2` are those rates (else increments / dt).
    """

    t: np.ndarray
    dt: np.ndarray
    u: np.ndarray
    rpy_rad: np.ndarray | None = None
    rates: tuple[np.ndarray, np.ndarray] | None = dataclasses.field(default=None, repr=False)

    NAME: ClassVar[str] = "IMU table"

    @classmethod
    def from_increments(cls, t, dt, dtheta_b, dvel_b, rpy_rad=None) -> "ImuTable":
        """From increments dtheta_b (n, 3) rad and dvel_b (n, 3) m/s."""
        u = np.empty((np.shape(dtheta_b)[0], LAYOUT.NU))
        u[:, LAYOUT.U_DTHETA_B_SLICE], u[:, LAYOUT.U_DVEL_B_SLICE] = dtheta_b, dvel_b
        return cls(np.asarray(t, float), np.asarray(dt, float), u, rpy_rad)

    @classmethod
    def from_rates(cls, t, dt, w_b_radps, f_b_mps2, rpy_rad=None) -> "ImuTable":
        """From mean rates over each interval: w_b_radps (n, 3) rad/s, f_b_mps2 (n, 3) m/s^2."""
        dt = np.asarray(dt, float)
        w, f = np.asarray(w_b_radps, float), np.asarray(f_b_mps2, float)
        table = cls.from_increments(t, dt, w * dt[:, None], f * dt[:, None], rpy_rad)
        table.rates = (w, f)
        return table

    @property
    def dtheta_b(self) -> np.ndarray:
        return self.u[:, LAYOUT.U_DTHETA_B_SLICE]

    @property
    def dvel_b(self) -> np.ndarray:
        return self.u[:, LAYOUT.U_DVEL_B_SLICE]

    @property
    def w_b_radps(self) -> np.ndarray:
        return self.rates[0] if self.rates is not None else self.dtheta_b / self.dt[:, None]

    @property
    def f_b_mps2(self) -> np.ndarray:
        return self.rates[1] if self.rates is not None else self.dvel_b / self.dt[:, None]

    @property
    def t_first(self) -> float:
        """Start of the first interval (s)."""
        return float(self.t[0] - self.dt[0])

    def check(self) -> "ImuTable":
        n = np.shape(self.t)[0] if np.ndim(self.t) == 1 else -1
        if n < 1:
            raise _bad(self.NAME, "t", f"shape {np.shape(self.t)}", "at least one interval, shape (n,)")
        check_column(self.NAME, "t", self.t, (n,), unit="s")
        if n > 1 and not (self.t[1:] > self.t[:-1]).all():
            row = int(np.flatnonzero(np.diff(self.t) <= 0)[0]) + 1
            raise _bad(self.NAME, "t", f"row {row} is not later than the row before", "increasing times")
        check_column(self.NAME, "dt", self.dt, (n,), positive=True, unit="s")
        check_column(self.NAME, "u", self.u, (n, LAYOUT.NU), unit="rad, m/s")
        if self.rpy_rad is not None:
            check_column(self.NAME, "rpy_rad", self.rpy_rad, (n, 3), unit="rad")
        return self

    def from_time(self, t_start: float) -> tuple["ImuTable", int]:
        """The table from `t_start` (s) on, and the number of intervals dropped: intervals
        ending at or before it are dropped, the one spanning it is cut at it (its mean rates
        kept, so its increments shrink)."""
        keep = self.t > t_start
        dt, u = self.dt[keep].copy(), self.u[keep]
        rates = None if self.rates is None else (self.rates[0][keep], self.rates[1][keep])
        new = min(dt[0], self.t[keep][0] - t_start) if dt.size else 0.0
        if dt.size and new != dt[0]:
            u = u.copy()
            if rates is not None:
                u[0, LAYOUT.U_DTHETA_B_SLICE], u[0, LAYOUT.U_DVEL_B_SLICE] = rates[0][0] * new, rates[1][0] * new
            else:
                u[0] = u[0] * (new / dt[0])
            dt[0] = new
        rpy = None if self.rpy_rad is None else self.rpy_rad[keep]
        return ImuTable(self.t[keep], dt, u, rpy, rates), int((~keep).sum())


@dataclasses.dataclass
class FixTable:
    """GNSS position fixes in the ENU frame at the run's origin: t (m,) s; p_enu_m (m, 3);
    sigma_enu_m (m, 3) 1-sigma per axis, m, > 0; v_en_mps (m, 2) horizontal velocity East,
    North (m/s, NaN when the receiver gave none)."""

    t: np.ndarray
    p_enu_m: np.ndarray
    sigma_enu_m: np.ndarray
    v_en_mps: np.ndarray

    NAME: ClassVar[str] = "GNSS fix table"

    @classmethod
    def empty(cls) -> "FixTable":
        return cls(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 2)))

    def select(self, mask) -> "FixTable":
        return FixTable(self.t[mask], self.p_enu_m[mask], self.sigma_enu_m[mask], self.v_en_mps[mask])

    def check(self) -> "FixTable":
        n = np.shape(self.t)[0] if np.ndim(self.t) == 1 else -1
        check_column(self.NAME, "t", self.t, (max(n, 0),), unit="s")
        check_column(self.NAME, "p_enu_m", self.p_enu_m, (n, 3), unit="m")
        check_column(self.NAME, "sigma_enu_m", self.sigma_enu_m, (n, 3), positive=True, unit="m")
        check_column(self.NAME, "v_en_mps", self.v_en_mps, (n, 2), finite=False)
        return self


@dataclasses.dataclass
class VelocityTable:
    """GNSS velocity of the antenna in the ENU frame at the run's origin: t (m,) s; v_enu_mps
    (m, 3); sigma_mps (m, 3) 1-sigma per axis, m/s, > 0 (NAV-PVT velocity, RMC course and
    speed, or a dataset's columns)."""

    t: np.ndarray
    v_enu_mps: np.ndarray
    sigma_mps: np.ndarray

    NAME: ClassVar[str] = "GNSS velocity table"

    def select(self, mask) -> "VelocityTable":
        return VelocityTable(self.t[mask], self.v_enu_mps[mask], self.sigma_mps[mask])

    def check(self) -> "VelocityTable":
        n = np.shape(self.t)[0] if np.ndim(self.t) == 1 else -1
        check_column(self.NAME, "t", self.t, (max(n, 0),), unit="s")
        check_column(self.NAME, "v_enu_mps", self.v_enu_mps, (n, 3), unit="m/s")
        check_column(self.NAME, "sigma_mps", self.sigma_mps, (n, 3), positive=True, unit="m/s")
        return self


SAT_R_M, SAT_V_MPS, SAT_A_MPS2 = slice(0, 3), slice(3, 6), slice(6, 9)
"""Columns of a satellite state block (n, 9): ECEF position m, velocity m/s, acceleration m/s^2."""


@dataclasses.dataclass
class SatelliteTable:
    """Measurements of one satellite observable (`KIND`, in `UNIT`).

    t (n,) s; sat_id (n,) int (NORAD id or PRN); z (n,) the measurement; sigma, its 1-sigma
    (a scalar or (n,), > 0; the record's R is sigma^2, or for the Doppler-rate the
    generated `leonav_doppler_rate_variance`); sat_ecef (n, 9): the satellite's Earth-fixed
    state at t, columns `SAT_R_M` (m), `SAT_V_MPS` (m/s, Earth-relative), `SAT_A_MPS2`
    (m/s^2) (pseudorange: at transmit time, in the ECEF frame of the transmit epoch);
    ref_ecef (n, 9) or None: the reference satellite of a differenced observable, same
    columns (zeros in the records when None); interval_s (n,) or a scalar, and sat_prev_r_m
    (n, 3), or None: a time-differenced observable's span (t - interval_s, t] (s, > 0) and the
    satellite's ECEF position (m) at its start (aux `dt_phase`, `r_S_prev_ecef`); tone_offset_hz
    (n,), a scalar or None (0): a carrier phase's tone offset from the channel centre, Hz (aux
    `df_tone`).
    """

    t: np.ndarray
    sat_id: np.ndarray
    z: np.ndarray
    sigma: np.ndarray | float
    sat_ecef: np.ndarray
    ref_ecef: np.ndarray | None = None
    interval_s: np.ndarray | float | None = None
    sat_prev_r_m: np.ndarray | None = None
    tone_offset_hz: np.ndarray | float | None = None

    KIND: ClassVar[str] = ""
    UNIT: ClassVar[str] = ""

    @classmethod
    def empty(cls) -> "SatelliteTable":
        return cls(np.zeros(0), np.zeros(0, int), np.zeros(0), np.zeros(0), np.zeros((0, 9)))

    @property
    def name(self) -> str:
        return f"{self.KIND} table"

    def select(self, mask) -> "SatelliteTable":
        sig = self.sigma if np.ndim(self.sigma) == 0 else np.asarray(self.sigma)[mask]
        ref = None if self.ref_ecef is None else self.ref_ecef[mask]
        span = self.interval_s if self.interval_s is None or np.ndim(self.interval_s) == 0 else \
            np.asarray(self.interval_s)[mask]
        prev = None if self.sat_prev_r_m is None else self.sat_prev_r_m[mask]
        df = self.tone_offset_hz if self.tone_offset_hz is None or np.ndim(self.tone_offset_hz) == 0 else \
            np.asarray(self.tone_offset_hz)[mask]
        return type(self)(self.t[mask], self.sat_id[mask], self.z[mask], sig, self.sat_ecef[mask], ref, span, prev,
                          df)

    def check(self) -> "SatelliteTable":
        n = np.shape(self.t)[0] if np.ndim(self.t) == 1 else -1
        name = self.name
        check_column(name, "t", self.t, (max(n, 0),), unit="s")
        check_column(name, "sat_id", self.sat_id, (n,), finite=False)
        check_column(name, "z", self.z, (n,), unit=self.UNIT)
        check_column(name, "sigma", self.sigma, () if np.ndim(self.sigma) == 0 else (n,), positive=True,
                     unit=self.UNIT)
        check_column(name, "sat_ecef", self.sat_ecef, (n, 9), unit="m, m/s, m/s^2")
        if self.ref_ecef is not None:
            check_column(name, "ref_ecef", self.ref_ecef, (n, 9), unit="m, m/s, m/s^2")
        if self.interval_s is not None:
            check_column(name, "interval_s", self.interval_s, () if np.ndim(self.interval_s) == 0 else (n,),
                         positive=True, unit="s")
        if self.sat_prev_r_m is not None:
            check_column(name, "sat_prev_r_m", self.sat_prev_r_m, (n, 3), unit="m")
        if self.tone_offset_hz is not None:
            check_column(name, "tone_offset_hz", self.tone_offset_hz,
                         () if np.ndim(self.tone_offset_hz) == 0 else (n,), unit="Hz")
        return self


def _satellite_table(o) -> type:
    """The table class of satellite observable `o` (registry entry); one that reads a reference
    satellite (a differenced observable) requires `ref_ecef`."""
    def check(self):
        if o.reads_ref and self.ref_ecef is None:
            raise _bad(self.name, "ref_ecef", "missing", "the reference satellite's state (n, 9)")
        if o.reads_interval and (self.interval_s is None or self.sat_prev_r_m is None):
            raise _bad(self.name, "interval_s" if self.interval_s is None else "sat_prev_r_m", "missing",
                       "the interval (s) each time difference spans and the satellite's position (m) at its start")
        return SatelliteTable.check(self)

    body = {"KIND": o.suffix, "UNIT": o.unit, "__doc__": f"{o.doc} ({o.unit}); see SatelliteTable."}
    if o.reads_ref or o.reads_interval:
        body["check"] = check
    return type(f"{o.suffix.title().replace('_', '')}Table", (SatelliteTable,), body)


SATELLITE_TABLES = {o.suffix: _satellite_table(o) for o in model.OBSERVABLES if o.table == "satellite"}
"""Table class of each satellite observable, by its suffix (from the registry)."""
globals().update({cls.__name__: cls for cls in SATELLITE_TABLES.values()})   # picklable by name
PseudorangeTable = SATELLITE_TABLES["pseudorange"]
DopplerRateTable = SATELLITE_TABLES["doppler_rate"]
DopplerTable = SATELLITE_TABLES["doppler"]
OfdmRangeDiffTable = SATELLITE_TABLES["ofdm_range_diff"]
CarrierPhaseTable = SATELLITE_TABLES["carrier_phase"]


@dataclasses.dataclass
class LocalSensorTable:
    """Measurements of a sensor on the vehicle (a barometer, a magnetometer): one table kind for
    every local sensor. `stream`: the sensor's record stream (its mode word); t (n,) s; z (n, k)
    one column per observable of the stream (kind-id order; a scalar sensor has k = 1), in their
    units; sigma: 1-sigma per column, a scalar, (k,) or (n, k), > 0."""

    stream: str
    t: np.ndarray
    z: np.ndarray
    sigma: np.ndarray | float

    @classmethod
    def empty(cls, stream: str) -> "LocalSensorTable":
        k = len(model.stream_observables(stream))
        return cls(stream, np.zeros(0), np.zeros((0, k)), 1.0)

    @property
    def name(self) -> str:
        return f"{self.stream} table"

    @property
    def observables(self) -> tuple:
        return model.stream_observables(self.stream)

    def sigma_columns(self) -> np.ndarray:
        """sigma broadcast to (n, k)."""
        return np.broadcast_to(np.asarray(self.sigma, float), np.shape(self.z)).copy()

    def select(self, mask) -> "LocalSensorTable":
        sig = self.sigma if np.ndim(self.sigma) < 2 else np.asarray(self.sigma)[mask]
        return LocalSensorTable(self.stream, self.t[mask], self.z[mask], sig)

    def check(self) -> "LocalSensorTable":
        obs = self.observables
        if not obs or any(o.table != "local" for o in obs):
            raise _bad("local sensor table", "stream", repr(self.stream),
                       f"a local sensor's stream ({', '.join(model.LOCAL_SENSORS) or 'none declared'})")
        n = np.shape(self.t)[0] if np.ndim(self.t) == 1 else -1
        check_column(self.name, "t", self.t, (max(n, 0),), unit="s")
        check_column(self.name, "z", self.z, (n, len(obs)), unit=", ".join(o.unit for o in obs))
        shape = np.shape(self.sigma)
        if shape not in ((), (len(obs),), (n, len(obs))):
            raise _bad(self.name, "sigma", f"shape {shape}", f"a scalar, ({len(obs)},) or ({n}, {len(obs)})")
        check_column(self.name, "sigma", self.sigma, shape, positive=True)
        return self
