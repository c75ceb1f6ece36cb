"""`assemble`: sensor tables + parameters + prior -> one `FilterInputs` for the generated C loop.

Rules (the same for every source):
- every table is checked first (`tables.*.check`: one UserInputError naming the field);
- the filter starts at the first IMU interval's start, or where `FirstFixPrior` puts it;
  measurements outside [start, last IMU sample] are dropped and counted
  (`fixes_outside_imu_span`, `<kind>_outside_imu_span`), as is the initializing fix;
- records per stream (`STREAMS`): IMU increments, fixes as POS_E/N/U, each satellite
  observable with its aux (satellite states, averaged specific force) and R
  (`measurements.py`); `FilterInputs.merged(streams)` merges the IMU records with the
  chosen streams in the fixed `STREAMS` order (at equal t: IMU first, then that order);
- a GNSS observation table (`gnss_obs.py`) gives the GNSS_PSEUDORANGE and GNSS_RANGE_RATE
  streams and starts the receiver clock from its single-point clocks (`apply_clock_start`).
"""
from __future__ import annotations

import dataclasses
import datetime as _dt
from typing import Iterable, Sequence

import numpy as np

from leonav_runtime.core import model, navfuncs, records
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.inputs.consider import OrbitConsider
from leonav_runtime.inputs.gnss_obs import GnssObservationTable, apply_clock_start, gnss_records
from leonav_runtime.inputs.imu import averaged_specific_force, imu_records
from leonav_runtime.inputs.measurements import fix_records, local_records, satellite_records, velocity_records
from leonav_runtime.inputs.prior import FirstFixPrior, Prior, first_fix_prior
from leonav_runtime.inputs.tables import FixTable, ImuTable, LocalSensorTable, SatelliteTable, VelocityTable

STREAMS = model.STREAMS
"""Record streams, in merge order: the IMU, then each observable's stream in kind-id order (registry)."""


@dataclasses.dataclass
class FilterInputs:
    """Everything the filter runs on, on one time axis (s since `epoch_utc` when known).

    records: stream name (`STREAMS`) -> record array (RECORD_DTYPE, time-ordered);
    x0 (NX,), P0 (NDX, NDX), params (NP,); the tables as used (IMU from the start on,
    measurements inside the IMU span); notes, counts and `init` (how x0/P0 were made)
    for the run's report; origin (lat rad, lon rad, h m) of the ENU frame.
    """

    records: dict[str, np.ndarray]
    x0: np.ndarray
    P0: np.ndarray
    params: np.ndarray
    imu: ImuTable
    fixes: FixTable
    satellites: dict[str, SatelliteTable]
    gnss: GnssObservationTable = dataclasses.field(default_factory=GnssObservationTable.empty)
    local: dict[str, LocalSensorTable] = dataclasses.field(default_factory=dict)
    notes: list[str] = dataclasses.field(default_factory=list)
    counts: dict = dataclasses.field(default_factory=dict)
    init: dict = dataclasses.field(default_factory=dict)
    epoch_utc: _dt.datetime | None = None
    origin: tuple[float, float, float] | None = None

    @property
    def f_c_hz(self) -> float:
        """Beacon carrier f_c (Hz) of the Doppler and Doppler-rate models (from params)."""
        from leonav_runtime.gen.state_layout import P_F_C_HZ

        return float(self.params[P_F_C_HZ])

    def merged(self, streams: Iterable[str] | None = None) -> np.ndarray:
        """IMU records merged with `streams` (default: all) into one time-ordered stream."""
        want = set(STREAMS if streams is None else streams)
        unknown = want - set(STREAMS)
        if unknown:
            raise UserInputError(f"streams: {sorted(unknown)[0]!r}: expected some of {', '.join(STREAMS)}")
        return records.merge_records(self.records["imu"], *(self.records[s] for s in STREAMS[1:]
                                                            if s in want and s in self.records))


def _inside(t: np.ndarray, t_start: float, t_end: float) -> np.ndarray:
    return (t >= t_start) & (t <= t_end)


def assemble(imu: ImuTable, params: np.ndarray, prior: Prior | FirstFixPrior, *, fixes: FixTable | None = None,
             satellites: Sequence[SatelliteTable] = (), nav: navfuncs.NavFunctions | None = None,
             notes: list[str] | None = None, epoch_utc: _dt.datetime | None = None,
             origin: tuple[float, float, float] | None = None,
             gnss: GnssObservationTable | None = None, orbit_consider: OrbitConsider | None = None,
             local: Sequence[LocalSensorTable] = (), velocity: VelocityTable | None = None,
             corrections=None) -> FilterInputs:
    """Records, x0, P0 and p from sensor tables (module doc). params: (NP,) (`filter_params`);
    prior: x0/P0 given (`Prior`) or made from the data (`FirstFixPrior`); satellites: at
    most one table per observable kind; gnss: code / Doppler observations of a GNSS receiver;
    orbit_consider: satellite orbit errors added to the satellite records' R (consider term,
    Jacobian at the prior's state); local: at most one table per local sensor (barometer, ...);
    velocity: GNSS velocity of the antenna (the VEL stream); corrections: a base's differential
    corrections (`inputs.corrections.DifferentialCorrections`, its epoch_unix set) applied to the
    satellite tables it covers."""
    nav = nav or navfuncs.NavFunctions(params=params)
    notes = list(notes or [])
    imu.check()
    if fixes is not None:
        fixes.check()
    if velocity is not None:
        velocity.check()
    kinds = [tab.KIND for tab in satellites]
    if len(set(kinds)) < len(kinds) or not all(kinds):
        raise UserInputError(f"satellite tables: {kinds}: expected at most one table per observable kind")
    for tab in satellites:
        tab.check()
    if gnss is not None:
        gnss.check()
    streams = [tab.stream for tab in local]
    if len(set(streams)) < len(streams):
        raise UserInputError(f"local sensor tables: {streams}: expected at most one table per sensor")
    for tab in local:
        tab.check()
    params = np.asarray(params, dtype=np.float64)
    check_params = nav.layout.NP
    if params.shape != (check_params,) or not np.all(np.isfinite(params)):
        raise UserInputError(f"params: shape {params.shape}: expected ({check_params},) finite values")

    init_fix, n_before = -1, 0
    if isinstance(prior, FirstFixPrior):
        prior, imu, init_fix, n_before = first_fix_prior(prior, imu, fixes, nav, notes)
    t_start = imu.t_first if prior.t_start_s is None else prior.t_start_s
    t_end = float(imu.t[-1])
    out = {"imu": imu_records(imu)}
    counts: dict = {"imu_records_before_start": n_before}

    used_fixes = FixTable.empty()
    if fixes is not None:
        inside = _inside(fixes.t, t_start, t_end)
        if init_fix >= 0:
            inside[init_fix] = False
        counts["fixes_outside_imu_span"] = int((~inside).sum()) - (init_fix >= 0)
        used_fixes = fixes if inside.all() else fixes.select(inside)
    out["fix"] = fix_records(used_fixes, nav, imu)
    f_b_avg = f_b_span_s = None
    if velocity is not None:
        inside = _inside(velocity.t, t_start, t_end)
        counts["velocity_outside_imu_span"] = int((~inside).sum())
        f_b_avg, f_b_span_s = averaged_specific_force(imu.dvel_b, imu.dt)
        out["vel"] = velocity_records(velocity.select(inside), imu, f_b_avg, nav)
        counts["vel_records"] = int(out["vel"].size)

    used_sats: dict[str, SatelliteTable] = {}
    for tab in satellites:
        inside = _inside(tab.t, t_start, t_end)
        counts[f"{tab.KIND}_outside_imu_span"] = int((~inside).sum())
        used = used_sats[tab.KIND] = tab if inside.all() else tab.select(inside)
        if used.t.size and f_b_avg is None:
            # receiver acceleration input: the specific force averaged up to the latest IMU sample
            f_b_avg, f_b_span_s = averaged_specific_force(imu.dvel_b, imu.dt)
            counts["f_b_average_s"] = f_b_span_s
        out[tab.KIND] = (satellite_records(used, imu, f_b_avg, f_b_span_s, params, nav, orbit_consider, prior.x0,
                                           corrections)
                         if used.t.size else np.zeros(0, records.RECORD_DTYPE))

    used_gnss = GnssObservationTable.empty()
    x0, P0, init = prior.x0, prior.P0, {"start_s": t_start} | prior.init
    if gnss is not None:
        inside = _inside(gnss.t, t_start, t_end)
        counts["gnss_outside_imu_span"] = int((~inside).sum())
        used_gnss = gnss if inside.all() else gnss.select(inside)
        out["gnss_pseudorange"], out["gnss_range_rate"] = gnss_records(used_gnss, nav)
        if len(used_gnss):
            x0, P0, params, clock_init = apply_clock_start(x0, P0, params, gnss, t_start, nav.layout)
            init |= clock_init

    used_local: dict[str, LocalSensorTable] = {}
    for tab in local:
        inside = _inside(tab.t, t_start, t_end)
        counts[f"{tab.stream}_outside_imu_span"] = int((~inside).sum())
        used = used_local[tab.stream] = tab if inside.all() else tab.select(inside)
        needs_f_b = any(o.reads_specific_force for o in tab.observables)
        if needs_f_b and f_b_avg is None:
            f_b_avg, f_b_span_s = averaged_specific_force(imu.dvel_b, imu.dt)
        out[tab.stream] = local_records(used, imu, f_b_avg if needs_f_b else None, nav)
        counts[f"{tab.stream}_records"] = int(out[tab.stream].size)

    counts |= {"imu_records": int(out["imu"].size), "fix_epochs": int(used_fixes.t.size)}
    for kind in list(used_sats) + (["gnss_pseudorange", "gnss_range_rate"] if gnss is not None else []):
        counts[f"{kind}_records"] = int(out[kind].size)
    return FilterInputs(out, x0, P0, params, imu, used_fixes, used_sats, used_gnss, used_local, notes, counts, init,
                        epoch_utc, origin)
