"""Arriving sensor data -> tables -> records, through `leonav_runtime.inputs` (the one road).

`StreamingRoad` is the causal twin of `replay.run.decode_inputs`:
- time: `timemap.StreamingTimeMap` (GNSS tags) and `imu_timing.OnlineImuTiming` (sample times);
- start: once there is a time map, a usable fix and `attitude_window_s` of IMU after the start,
  the buffered IMU samples and fixes become an `ImuTable` and a `FixTable` on one axis (t = 0
  at the first buffered IMU sample, as in the replay) and go through `inputs.assemble` with the
  replay's `FirstFixPrior` (`replay.run.replay_prior`): x0, P0, p and the first records;
- then, for every arriving IMU sample, one `ImuTable` row -> `inputs.imu_records`; for every
  fix epoch, `gnss_table.fix_table` rows -> `inputs.fix_records`; for every Doppler-rate or
  carrier-phase measurement, a `SatelliteTable` row -> `inputs.satellite_records` with the specific force
  averaged over the IMU samples up to it (`inputs.averaged_specific_force` on the last
  `ROLLING_IMU_S` of samples), corrected there by a base's differential corrections when given
  (`inputs.corrections`, as every source's). A measurement is released once an IMU sample at or after its
  time has arrived (the road's rule: measurements inside the IMU span), earlier than the start
  it is dropped and counted.
"""
from __future__ import annotations

import collections
import dataclasses
import datetime as _dt
import math

import numpy as np

from leonav.hardware.records import GnssFix
from leonav_runtime.core import navfuncs, records
from leonav_runtime.inputs import (FilterInputs, FixTable, ImuTable, SatelliteTable, assemble,
                                   averaged_specific_force, filter_params, fix_records, imu_records,
                                   satellite_records)
from leonav_runtime.nav.gnss_stream import FixAssembler, epoch_fixes
from leonav_runtime.nav.imu_timing import OnlineImuTiming
from leonav_runtime.nav.timemap import StreamingTimeMap
from leonav_runtime.replay.gnss_table import fix_height_m, usable_fix
from leonav_runtime.replay.options import ReplayOptions, latency_given_s, latency_values
from leonav_runtime.replay.run import replay_prior
from leonav_runtime.replay.timebase import filter_profile, utc_of

ROLLING_IMU_S = 2.0          # IMU samples kept after the start for the averaged specific force
PRE_START_BUFFER_S = 10.0    # IMU samples kept while waiting for the start
MAX_PENDING = 2000           # measurements waiting for the IMU (none come while it is lost): the oldest go


@dataclasses.dataclass
class RoadConfig:
    streams: tuple[str, ...] = ("fix",)      # measurement streams fused with the IMU (inputs.STREAMS names)
    origin_deg: tuple[float, float, float] | None = None
    yaw_deg: float | None = None
    gnss_baud: int | None = None
    imu_baud: int | None = None
    gnss_latency_s: float | str = 0.0   # or "estimate": the fix latency state (replay.options)
    f_c_hz: float = math.nan
    doppler_rate_sigma_floor_hz_s: float = 0.5


class StreamingRoad:
    """Feed `add_gnss`, `add_imu`, `add_satellite_table`; take the filter's records with `take()`."""

    def __init__(self, cfg: RoadConfig, nav: navfuncs.NavFunctions | None = None, corrections=None,
                 operator=None) -> None:
        """corrections: a base's differential corrections (`inputs.corrections.DifferentialCorrections`,
        filled by `base.client.CorrectionsClient`), applied to the Doppler-rate as it is released;
        operator: an `orbits.operator_folder.OperatorFolder` (--operator-ephemerides) whose files'
        covariance enters the Doppler-rate's R as the consider term (as in the replay)."""
        self.cfg = cfg
        self.corrections = corrections
        self.operator = operator
        self.nav = nav or navfuncs.NavFunctions()
        self.tmap = StreamingTimeMap(cfg.gnss_baud, latency_given_s(cfg.gnss_latency_s))
        self.timing = OnlineImuTiming(cfg.imu_baud)
        self.assembler = FixAssembler()
        self.notes: set[str] = set()
        self.started = False
        self.inputs: FilterInputs | None = None     # the start (assemble's output)
        self.epoch_unix = math.nan
        self.origin: tuple[float, float, float] | None = None
        self.params: np.ndarray | None = None
        self.t_start = math.nan
        self.t_imu = -math.inf                      # time of the latest IMU sample on the axis
        self.imu_dt = 0.0                           # its interval
        self._pre_imu: collections.deque = collections.deque()   # (t_mono_fit, w, f, rpy) before the start
        self._pre_epochs: list[list] = []            # fix epochs (records) before the start
        self._roll: collections.deque = collections.deque()      # (t, dt, dvel) after the start
        self._pending: list[tuple[float, str, object]] = []      # (t, stream, one-row table)
        self._out: list[np.ndarray] = []
        self.counts = collections.Counter()
        self.last_fix_mono = -math.inf

    # -- arriving data
    def add_gnss(self, rec) -> None:
        self.tmap.add(rec)
        for epoch in self.assembler.add(rec):
            self._fix_epoch(epoch)
        if isinstance(rec, GnssFix):
            self.counts["gnss_fixes_received"] += 1

    def poll(self, now_mono: float) -> None:
        """Fix epochs that waited too long for their GST; try to start."""
        for epoch in self.assembler.poll(now_mono):
            self._fix_epoch(epoch)
        if not self.started:
            self._try_start()

    def flush(self) -> None:
        for epoch in self.assembler.flush():
            self._fix_epoch(epoch)

    def add_imu(self, samples: list, stamp_s: float) -> None:
        """Samples that arrived in one read at `stamp_s` (host monotonic s)."""
        times = self.timing.add(stamp_s, len(samples))
        for s, t_mono, idx in zip(samples, times, self.timing.last_indices):
            self.counts["imu_samples"] += 1
            if not self.started:
                self._pre_imu.append((t_mono, s.w_b_radps, s.f_b_mps2, s.rpy_rad, idx))
                while self._pre_imu and self._pre_imu[-1][0] - self._pre_imu[0][0] > PRE_START_BUFFER_S:
                    self._pre_imu.popleft()
                continue
            self._imu_row(t_mono, s)
        if not self.started:
            self._try_start()
        else:
            self._release()

    def add_satellite_table(self, table: SatelliteTable) -> None:
        """Doppler-rate or carrier-phase measurements (t on this road's axis, satellite states filled)."""
        stream = table.KIND
        if stream not in self.cfg.streams or not self.started:
            self.counts[f"{stream}_not_used"] += int(table.t.size)
            return
        for k in range(table.t.size):
            self._measurement(float(table.t[k]), stream, table.select(np.array([k])))
        self._release()

    def take(self) -> np.ndarray:
        """Records ready for the filter since the last call (arrival order; the stepper merges)."""
        if not self._out:
            return np.zeros(0, records.RECORD_DTYPE)
        out = self._out[0] if len(self._out) == 1 else np.concatenate(self._out)
        self._out = []
        return out

    # -- time axis
    def t_of_mono(self, t_mono: float) -> float:
        return self.tmap.to_utc(t_mono) - self.epoch_unix

    @property
    def epoch_utc(self) -> _dt.datetime | None:
        return utc_of(self.epoch_unix) if math.isfinite(self.epoch_unix) else None

    # -- fixes
    def _fix_epoch(self, epoch: list) -> None:
        self.last_fix_mono = max((r.t_mono_s for r in epoch if isinstance(r, GnssFix)), default=self.last_fix_mono)
        if not self.started:
            self._pre_epochs.append(epoch)
            if len(self._pre_epochs) > 600:
                self._pre_epochs.pop(0)
            return
        table = self._fix_table([epoch])
        for k in range(table.t.size):
            self._measurement(float(table.t[k]), "fix", table.select(np.array([k])))
        self._release()

    def _fix_table(self, epochs: list[list], count: bool = True) -> FixTable:
        notes: list[str] = []
        tabs = []
        for ep in epochs:
            tab, counts = epoch_fixes(ep, lambda t: self.tmap.to_utc(float(t)), self.epoch_unix, self.origin, notes)
            if count:
                for key in ("gnss_fixes_unusable", "gst_rmc_unreadable"):
                    self.counts[key] += counts.get(key, 0)
                for src, n in counts.get("fix_sigma_source", {}).items():
                    self.counts[f"fix_sigma_{src}"] += n
            tabs.append(tab)
        if count:
            self.notes.update(notes)
        tabs = [t for t in tabs if t.t.size]
        if not tabs:
            return FixTable.empty()
        return FixTable(*(np.concatenate([getattr(t, f) for t in tabs]) for f in ("t", "p_enu_m", "sigma_enu_m",
                                                                                  "v_en_mps")))

    # -- measurements waiting for the IMU
    def _measurement(self, t: float, stream: str, table) -> None:
        if t < self.t_start:
            self.counts[f"{stream}_before_start"] += 1
            return
        if stream not in self.cfg.streams:
            self.counts[f"{stream}_not_fused"] += 1
            return
        self._pending.append((t, stream, table))
        if len(self._pending) > MAX_PENDING:
            self._pending.pop(0)
            self.counts["waiting_for_imu_dropped"] += 1

    def _release(self) -> None:
        if not self._pending:
            return
        due = [p for p in self._pending if p[0] <= self.t_imu + 1e-9]
        if not due:
            return
        self._pending = [p for p in self._pending if p[0] > self.t_imu + 1e-9]
        for t, stream, table in due:
            if stream == "fix":
                self._out.append(fix_records(table, self.nav))
            else:
                roll = self._roll_table()
                f_b, span = averaged_specific_force(roll.dvel_b, roll.dt)
                consider, provider = self._consider(table)
                self._out.append(satellite_records(table, roll, f_b, span, self.params, self.nav,
                                                   consider, self.inputs.x0, corrections=self.corrections))
                if provider is not None:    # covered: a file for the satellite over the record's time
                    missing = provider.uncovered_records
                    self.counts[f"{stream}_operator_covariance"] += int(table.t.size) - missing
                    self.counts[f"{stream}_without_operator_covariance"] += missing
            self.counts[f"{stream}_released"] += 1

    def _consider(self, table):
        """The operator files' covariance as the table's consider term, and its provider (None, None
        without --operator-ephemerides); records whose satellite has no covering file (none read yet
        included) keep their R and are counted."""
        if self.operator is None:
            return None, None
        from leonav_runtime.inputs.consider import OrbitConsider
        from leonav_runtime.orbits.operator_consider import OperatorCovariance

        provider = OperatorCovariance(self.operator.set, self.epoch_utc, self.operator.ids_to_names, quiet=True)
        return OrbitConsider({}, covariance={table.KIND: provider}), provider

    @property
    def pending(self) -> int:
        return len(self._pending)

    # -- IMU
    def _imu_row(self, t_mono: float, s) -> None:
        t = self.t_of_mono(t_mono)
        if not t > self.t_imu:
            self.counts["imu_time_not_increasing"] += 1
            t = self.t_imu + 1e-4
        dt = t - self.t_imu
        table = ImuTable.from_rates(np.array([t]), np.array([dt]), np.array([s.w_b_radps]),
                                    np.array([s.f_b_mps2]), np.array([s.rpy_rad]))
        self._out.append(imu_records(table))
        self._roll.append((t, dt, table.dvel_b[0].copy()))
        self.imu_dt = dt
        while self._roll and t - self._roll[0][0] > ROLLING_IMU_S:
            self._roll.popleft()
        self.t_imu = t

    def _roll_table(self) -> ImuTable:
        t = np.array([r[0] for r in self._roll])
        dt = np.array([r[1] for r in self._roll])
        dvel = np.array([r[2] for r in self._roll])
        return ImuTable.from_increments(t, dt, np.zeros_like(dvel), dvel)

    # -- the start
    def waiting_for(self) -> str:
        if not self.tmap.valid:
            return "GNSS time tags"
        if not self._pre_epochs:
            return "a GNSS fix"
        if len(self._pre_imu) < 3:
            return "IMU samples"
        return "1 s of IMU after the first fix"

    def _try_start(self) -> None:
        if not (self.tmap.valid and len(self._pre_imu) >= 3 and self._pre_epochs):
            return
        first = next((r for ep in self._pre_epochs for r in ep if isinstance(r, GnssFix) and usable_fix(r)), None)
        if first is None and self.cfg.origin_deg is None:
            return
        # the buffered samples on the line fitted so far (as the replay puts all samples on its line)
        t_mono = np.array(self.timing.times_of([p[4] for p in self._pre_imu]))
        utc = np.array([self.tmap.to_utc(t) for t in t_mono])
        epoch = float(utc[0])
        t = utc - epoch
        if self.cfg.origin_deg is not None:
            lat, lon, h = self.cfg.origin_deg
            origin = (math.radians(lat), math.radians(lon), float(h))
        else:
            origin = (first.lat_rad, first.lon_rad, fix_height_m(first))
        self.epoch_unix, self.origin = epoch, origin
        if self.corrections is not None:
            self.corrections.epoch_unix = epoch
        fixes = self._fix_table(self._pre_epochs, count=False)
        later = fixes.t >= t[0] - 0.2
        if not later.any():
            return
        t_fix = float(fixes.t[later][0])
        if t[-1] < max(t[1], t_fix) + 1.0 + 1e-9:      # FirstFixPrior's attitude window after the start
            return
        self._start(t, t_mono, self._fix_table(self._pre_epochs), origin)

    def _start(self, t: np.ndarray, t_mono: np.ndarray, fixes: FixTable, origin) -> None:
        pre = list(self._pre_imu)
        w = np.array([p[1] for p in pre], float)
        f = np.array([p[2] for p in pre], float)
        rpy = np.array([p[3] for p in pre], float)
        for k in range(1, t.size):      # a line refitted later could not reorder them, but be sure
            if not t[k] > t[k - 1]:
                t[k] = t[k - 1] + 1e-4
                self.counts["imu_time_not_increasing"] += 1
        imu = ImuTable.from_rates(t[1:], np.diff(t), w[1:], f[1:], rpy[1:])
        profile = filter_profile(float(np.median(np.diff(t))), quantized=True)
        self.params = filter_params(origin, profile, self.cfg.f_c_hz, latency_values(self.cfg.gnss_latency_s))
        self.nav.params = self.params
        inside = fixes.t <= imu.t[-1]
        notes: list[str] = []
        prior = replay_prior(ReplayOptions(yaw_deg=self.cfg.yaw_deg, gnss_latency_s=self.cfg.gnss_latency_s), profile)
        inputs = assemble(imu, self.params, prior, fixes=fixes.select(inside), nav=self.nav, notes=notes,
                          epoch_utc=self.epoch_utc, origin=origin)
        self.notes.update(notes)
        self.inputs = inputs
        self.t_start = float(inputs.init["start_s"])
        self.started = True
        self.counts["imu_samples_before_start"] = int(inputs.counts.get("imu_records_before_start", 0))
        self._out.append(inputs.merged([s for s in self.cfg.streams if s == "fix"]))
        self.counts["fix_released"] += int(inputs.fixes.t.size)
        self.t_imu = float(inputs.imu.t[-1])
        for k in range(max(0, inputs.imu.t.size - 200), inputs.imu.t.size):
            self._roll.append((float(inputs.imu.t[k]), float(inputs.imu.dt[k]), inputs.imu.dvel_b[k].copy()))
        for k in np.flatnonzero(~inside):
            self._measurement(float(fixes.t[k]), "fix", fixes.select(np.array([k])))
        self._pre_imu.clear()
        self._pre_epochs.clear()
        self._release()
