"""A block of trials of one (mode, count) at once: the records `simulate.trial_records` gives,
built without running the input road per trial.

Every trial of a (mode, count) has the same record layout: the same times, kinds, satellites,
R and satellite states; only the IMU increments, the measured values z and the averaged
specific force in aux (it comes from the measured increments) differ. So the road runs once per
(mode, count) on a *template* (`assemble` with the true increments and z set to each value's
position), which gives the merged layout and where every drawn value goes; a block then draws
each trial from its own stream (`simulate.trial_draws`, the same draws in the same order) and
fills the values of all its trials with array operations. The results equal `trial_records`
bit for bit (tests/test_simulate.py), so seeds give the same sweep as before.

The realism switches (realism.py) change R and aux per trial (inflate-r, consider): a scenario
with any of them active takes the road per trial.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from leonav_runtime.core import model, navfuncs
from leonav_runtime.inputs import ImuTable, LocalSensorTable, Prior, assemble
from leonav_runtime.inputs.imu import F_B_AVERAGE_S, latest_sample
from leonav_runtime.scenarios.load import mode_of
from leonav_runtime.simulation import realism, simulate


@dataclass
class TrialBlock:
    """Trials of one (mode, count): records (B, nrec) RECORD_DTYPE, one stream per trial; x0
    (B, NX); x_true (B, n+1, NX) truth with each trial's sensor errors; params (NP,) of the filter
    for every trial (realism compensation, else the setup's) or (B, NP) per trial."""

    records: np.ndarray
    x0: np.ndarray
    x_true: np.ndarray
    params: np.ndarray


@dataclass
class Template:
    """Where a trial's drawn values go in its merged record stream (module doc)."""

    rec: np.ndarray        # (nrec,) merged records, z and the IMU u and f_b still to fill
    imu_pos: np.ndarray    # (n,) positions of the IMU records (interval order)
    meas_pos: np.ndarray   # positions of the measurement records ...
    meas_src: np.ndarray   # ... and the index of each one's value in the trial's value vector
    fb_pos: np.ndarray     # positions of the records whose aux carries the averaged specific force
    fb_sample: np.ndarray  # the index into `fb_ends`/`fb_starts` of each of those records
    fb_ends: np.ndarray    # per distinct IMU sample: the averaging window's last sample ...
    fb_starts: np.ndarray  # ... and its first (inputs.imu.averaged_specific_force)
    tt: np.ndarray         # (n+1,) s, time of each IMU sample from the first


def _markers(n: int, offset: int) -> np.ndarray:
    return offset + np.arange(n, dtype=float)


def template(setup: simulate.Setup, nav: navfuncs.NavFunctions, mode: str, count: int) -> Template:
    """The layout of every trial of (mode, count), made once per setup by the road itself."""
    key = (mode, count)
    # kept on the instance, not as a field: dataclasses.replace(setup, scn=...) must not inherit it
    cache = setup.__dict__.setdefault("_block_templates", {})
    if key in cache:
        return cache[key]
    scn, L, parsed = setup.scn, nav.layout, mode_of(mode)
    n = setup.u_true.shape[0]
    dt = 1.0 / scn.imu_rate_hz
    imu = ImuTable(setup.t_imu[1:], np.full(n, dt), setup.u_true)
    # the value vector of a trial: each used satellite observable's z, then each local sensor's z
    # column by column; the template's z is each value's index in that vector
    tables, offset = [], 0
    for o in satellites_used(parsed):
        rows = simulate.selected_rows(setup, o.suffix, count)
        tables.append(simulate.satellite_table(o.suffix, setup.series[o.suffix], rows, _markers(rows.size, offset),
                                               simulate.noise_sigma(scn, o.suffix)))
        offset += rows.size
    local = []
    for token in parsed.local_sensors:
        k = setup.local_k[token]
        obs = [o for o in parsed.observables if o.token == token]
        z = _markers(k.size * len(obs), offset).reshape(len(obs), k.size).T
        local.append(LocalSensorTable(token, setup.t_imu[k], z, np.array([simulate.noise_sigma(scn, o.suffix)
                                                                           for o in obs])))
        offset += z.size
    inputs = assemble(imu, setup.params, Prior(setup.x_true[0], setup.P0), satellites=tables, nav=nav, local=local)
    rec = inputs.merged(parsed.streams)
    meas = rec["kind"] >= 0
    f_b_kinds = [nav.kind_id(t.KIND) for t in tables]
    f_b_kinds += [nav.kind_id(o.suffix) for t in local if any(o.reads_specific_force for o in t.observables)
                  for o in t.observables]
    fb_pos = np.flatnonzero(np.isin(rec["kind"], f_b_kinds))
    samples, fb_sample = np.unique(latest_sample(imu, rec["t"][fb_pos]), return_inverse=True)
    # averaged_specific_force's window of sample k: samples max(max(k, 1) - n_avg, 0) .. max(k, 1)
    n_avg = max(1, int(round(F_B_AVERAGE_S / float(np.median(imu.dt)))))
    ends = np.maximum(samples, 1)
    tpl = Template(rec, np.flatnonzero(~meas), np.flatnonzero(meas), rec["z"][meas].astype(np.int64), fb_pos,
                   fb_sample, ends, np.maximum(ends - n_avg, 0), np.concatenate([[0.0], np.cumsum(imu.dt)]))
    if tpl.imu_pos.size != n or tpl.meas_src.size != offset:
        raise RuntimeError(f"block template of {mode} x {count}: {tpl.imu_pos.size} IMU and {tpl.meas_src.size} "
                           f"measurement records, expected {n} and {offset}")
    cache[key] = tpl
    return tpl


def satellites_used(parsed) -> list:
    """The satellite observables a parsed mode uses, in the order trial_draws makes their parts."""
    return [o for o in simulate.satellites.satellite_observables() if o in parsed.observables]


def trial_block(setup: simulate.Setup, mode: str, count: int, rngs: list[np.random.Generator],
                nav: navfuncs.NavFunctions) -> TrialBlock:
    """Trials of `mode` with `count` Starlink satellites, one per stream in `rngs` (the records,
    x0 and truth `simulate.trial_records` gives for each stream, module doc)."""
    scn, L = setup.scn, nav.layout
    if realism.active(scn):
        trials = [simulate.trial_records(setup, mode, count, rng, nav) for rng in rngs]
        return TrialBlock(np.stack([t.records for t in trials]), np.stack([t.x0 for t in trials]),
                          np.stack([t.x_true for t in trials]), np.stack([t.params for t in trials]))
    tpl = template(setup, nav, mode, count)
    parsed = mode_of(mode)
    draws = [simulate.trial_draws(setup, parsed, count, rng, nav) for rng in rngs]
    B = len(draws)
    x_true = np.empty((B,) + setup.x_true.shape)
    x_true[:] = setup.x_true
    for name in draws[0].errors if draws else ():
        b = model.state_block(name)
        x_true[:, :, b.offset:b.offset + b.size] = np.stack([d.errors[name] for d in draws])
    values = [np.concatenate([p[2] for p in d.parts]
                             + [z.T.ravel() for _, z, _ in simulate.local_values(setup, nav, rng, parsed, x, 1.0)])
              for d, rng, x in zip(draws, rngs, x_true)]
    u = np.stack([d.u for d in draws])                                # (B, n, 6)
    recs = np.empty((B, tpl.rec.size), tpl.rec.dtype)
    recs[:] = tpl.rec
    recs["u"][:, tpl.imu_pos] = u
    if values and values[0].size:
        recs["z"][:, tpl.meas_pos] = np.stack(values)[:, tpl.meas_src]
    if tpl.fb_pos.size:
        dvel = u[:, :, L.U_DVEL_B_SLICE]
        dv = np.concatenate([np.zeros((B, 1, dvel.shape[2])), np.cumsum(dvel, axis=1)], axis=1)
        e, s = tpl.fb_ends, tpl.fb_starts
        f_b = (dv[:, e] - dv[:, s]) / (tpl.tt[e] - tpl.tt[s])[:, None]
        recs["aux"][:, tpl.fb_pos, L.AUX_F_B_SLICE] = f_b[:, tpl.fb_sample]
    return TrialBlock(recs, np.stack([d.x0 for d in draws]).reshape(B, L.NX), x_true, setup.params)
