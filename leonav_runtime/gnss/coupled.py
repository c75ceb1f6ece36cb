"""Tightly coupled GNSS: a receiver's code / Doppler observations into the IMU filter.

Modes (Python API and `leonav replay`), each merged with the IMU records:

    pseudorange+imu             GNSS_PSEUDORANGE (+ GNSS_RANGE_RATE where the receiver gives Doppler)
    pseudorange+leo-alpha+imu   the same plus the Starlink Doppler-rate

Steps, all on the generated models (no equations here):
1. `signals.gnss_rows`: the primary code signal of every satellite and epoch, its satellite
   state at transmit time from the broadcast ephemeris, the aux of the GNSS observables.
2. `single_point`: `spp.solve` over the epochs. It gives what a filter needs per row and
   cannot know before it has a position: the elevation (mask) and with it the variance of
   RTKLIB's error model, RAIM flags, and per epoch the receiver clock to start from.
3. `observation_table`: the rows the GNSS-only EKF takes (`gnss_ekf.filter_rows`) on the
   run's time axis (s since `epoch_utc`: t = t_gps - t_gps(epoch_utc)), whole-millisecond
   receiver clock jumps taken out of the pseudoranges (`gnss_ekf.clock_jumps_m`), as an
   `inputs.GnssObservationTable`; `inputs.assemble(..., gnss=table)` makes the records and
   starts the receiver clock.
4. `coupled_inputs` / `run_mode`: the Python API around steps 1-3 for an IMU table.

The position at the start comes from the first single-point solution (`spp_fixes` turns the
solutions into a fix table for `inputs.FirstFixPrior`), unless the caller gives fixes.
"""
from __future__ import annotations

import datetime as _dt
import math

import numpy as np

from leonav_runtime.core import navfuncs
from leonav_runtime.orbits import geometry
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.core import model
from leonav_runtime.core.filter import EKF, RunResult
from leonav_runtime.gen import constants as K
from leonav_runtime.gnss import spp as _spp
from leonav_runtime.gnss import time as gtime
from leonav_runtime.gnss.ephemeris import Ephemerides
from leonav_runtime.gnss.gnss_ekf import clock_jumps_m, filter_rows, filter_sigma_m, sat_ids
from leonav_runtime.gnss.observations import ObservationTable
from leonav_runtime.gnss.signals import REASONS, gnss_rows
from leonav_runtime.inputs import (FilterInputs, FirstFixPrior, FixTable, GnssObservationTable, ImuTable, Prior,
                                   assemble, filter_params)
SPP_FIX_MIN_SIGMA_M = 0.5     # floor of a single-point fix's 1-sigma per axis when it starts the filter


def single_point(obs: ObservationTable, eph: Ephemerides, klobuchar: np.ndarray | None, *,
                 elevation_mask_deg: float = K.GNSS_MASK_DEG, iono: bool = True, tropo: bool = True,
                 systems: str = "GEJC", cn0_mask_dbhz: float = 0.0, raim: bool = True,
                 nav: navfuncs.NavFunctions | None = None) -> _spp.SppResult:
    """Steps 1-2 of the module doc; a UserInputError when no row is usable (counts by reason)."""
    rows = gnss_rows(obs, eph, klobuchar=klobuchar, iono=iono, tropo=tropo, systems=systems,
                     cn0_mask_dbhz=cn0_mask_dbhz)
    if rows.counts.get("usable", 0) == 0:
        reasons = {k: v for k, v in rows.counts.items() if k in REASONS.values() and v}
        raise UserInputError(f"{obs.source or 'GNSS observations'}: no usable pseudorange (rows by reason: "
                             f"{reasons})")
    res = _spp.solve(rows, _spp.SppOptions(elevation_mask_deg=elevation_mask_deg, raim=raim),
                     approx_ecef_m=obs.approx_position_ecef_m, nav=nav)
    if not res.solved.any():
        by_status = {k: v for k, v in res.counts.items() if k.startswith("epochs_")}
        raise UserInputError(f"{obs.source or 'GNSS observations'}: no epoch has a single-point solution "
                             f"(epochs by status: {by_status})")
    filter_rows(res)   # counts the rows a filter could not take (`unfit_for_filter`)
    return res


def gps_epoch(epoch_utc: _dt.datetime) -> float:
    """GPS seconds of the run's t = 0 (a UTC datetime)."""
    return float(gtime.utc_to_gps_seconds(epoch_utc))


def observation_table(spp: _spp.SppResult, epoch_utc: _dt.datetime, *, use_range_rate: bool = True,
                      range_rate_sigma_mps: float = K.RANGE_RATE_SIGMA_MPS) -> GnssObservationTable:
    """Step 3 of the module doc: the filter rows of a single-point result on the run's axis."""
    t0 = gps_epoch(epoch_utc)
    rows = spp.rows
    idx = filter_rows(spp)
    rr = rows.range_rate_mps[idx] if use_range_rate else np.full(idx.size, np.nan)
    ok = spp.solved
    jumps = clock_jumps_m(spp)   # whole-millisecond receiver clock steps, taken out (gnss_ekf.py)
    return GnssObservationTable(
        t=rows.t_gps_s[idx] - t0, sat_id=sat_ids(rows, idx),
        pseudorange_m=rows.pseudorange_m[idx] - jumps[spp.epoch_index[idx]],
        sigma_pr_m=filter_sigma_m(spp, idx), range_rate_mps=np.asarray(rr, float).copy(),
        sigma_rr_mps=np.full(idx.size, float(range_rate_sigma_mps)), aux=rows.aux[idx].copy(),
        clock_t=spp.t_gps_s[ok] - t0, clock_m=spp.clock_m[ok] - jumps[ok], isb_m=spp.isb_m[ok].copy())


def spp_fixes(spp: _spp.SppResult, epoch_utc: _dt.datetime, origin) -> FixTable:
    """Single-point solutions as position fixes in ENU at `origin` (lat rad, lon rad, h m),
    1-sigma from their covariance (at least `SPP_FIX_MIN_SIGMA_M`), no velocity."""
    ok = np.flatnonzero(spp.solved)
    lat0, lon0, h0 = origin
    r0 = geometry.geodetic_to_ecef(lat0, lon0, h0)
    p = np.atleast_2d(geometry.ecef_to_enu(spp.r_ecef_m[ok], r0, lat0, lon0))
    cov = spp.cov_enu_m2[ok]
    sig = np.sqrt(np.maximum(np.stack([cov[:, 0, 0], cov[:, 1, 1], cov[:, 2, 2]], axis=1), SPP_FIX_MIN_SIGMA_M**2))
    return FixTable(spp.t_gps_s[ok] - gps_epoch(epoch_utc), p, sig, np.full((ok.size, 2), np.nan))


def first_solution_origin(spp: _spp.SppResult) -> tuple[float, float, float]:
    """(lat rad, lon rad, h m) of the first single-point solution."""
    e = int(np.flatnonzero(spp.solved)[0])
    return float(spp.lat_rad[e]), float(spp.lon_rad[e]), float(spp.height_m[e])


def coupled_inputs(imu: ImuTable, spp: _spp.SppResult, epoch_utc: _dt.datetime, profile, *,
                   prior: Prior | FirstFixPrior | None = None, origin=None, fixes: FixTable | None = None,
                   satellites=(), f_c_hz: float = K.STARLINK_BEACON_HZ, use_range_rate: bool = True,
                   nav: navfuncs.NavFunctions | None = None) -> FilterInputs:
    """Filter inputs of a tightly coupled run (Python API).

    imu: the IMU table on the run's axis (s since `epoch_utc`, with rpy_rad for the start's
    roll/pitch unless `prior` is a `Prior`); spp: `single_point` of the receiver's
    observations; profile: the IMU profile (`gen.profiles`); origin: ENU origin (default: the
    first single-point solution); fixes: start fixes (default: `spp_fixes`); satellites:
    further satellite tables (e.g. the Doppler-rate of `pseudorange+leo-alpha+imu`)."""
    origin = origin or first_solution_origin(spp)
    fixes = fixes if fixes is not None else spp_fixes(spp, epoch_utc, origin)
    prior = prior or FirstFixPrior(profile, attitude_source="the IMU's angle output",
                                   velocity_source="single-point solution (no velocity)")
    notes = [] if fixes.t.size == 0 else ["GNSS: start position from the first single-point solution of the "
                                          "receiver's pseudoranges"]
    return assemble(imu, filter_params(origin, profile, f_c_hz), prior, fixes=fixes, satellites=list(satellites),
                    nav=nav, notes=notes, epoch_utc=epoch_utc, origin=origin,
                    gnss=observation_table(spp, epoch_utc, use_range_rate=use_range_rate))


def run_mode(inputs: FilterInputs, mode: str, *, gate: float = K.CHI2_1DOF_999,
             nav: navfuncs.NavFunctions | None = None) -> tuple[np.ndarray, RunResult]:
    """(records, result) of one tightly coupled mode (e.g. pseudorange+imu) through the generated C loop."""
    parsed = model.parse_mode(mode, lambda o: o.table == "gnss_obs" or o.stream == "doppler_rate", "mode")
    if not any(o.table == "gnss_obs" for o in parsed.observables):
        raise UserInputError(f"mode {mode!r}: expected a tightly coupled mode (its words include pseudorange)")
    nav = nav or navfuncs.NavFunctions(params=inputs.params)
    recs = inputs.merged(parsed.streams)
    ekf = EKF(inputs.x0, inputs.P0, inputs.params, gate=gate or None, library=nav.library)
    return recs, ekf.run(recs)


def positions_ecef(x: np.ndarray, params: np.ndarray, nav: navfuncs.NavFunctions) -> np.ndarray:
    """Receiver ECEF position (n, 3) m of states x (n, NX)."""
    return np.array([nav.receiver_ecef(xi, params)[0] for xi in np.atleast_2d(x)])


def nis_summary(recs: np.ndarray, res: RunResult, kind: int) -> dict:
    """Applied and gated counts and the mean NIS of the applied records of one kind."""
    from leonav_runtime.core.filter import STATUS_APPLIED, STATUS_GATED

    k = recs["kind"] == kind
    applied = k & (res.status == STATUS_APPLIED)
    return {"applied": int(applied.sum()), "gated": int((k & (res.status == STATUS_GATED)).sum()),
            "mean_nis": float(np.mean(res.nis[applied])) if applied.any() else math.nan}
