"""A block of trials of one (mode, count) at once: the records `simulate.trial_records` gives,
built without running the input road per trial.

Every trial of a (mode, count) has the same record layout: the same times, kinds, satellites,
R and satellite states; only the IMU increments, the measured values z and the averaged
specific force in aux (it comes from the measured increments) differ. So the road runs once per
(mode, count) on a *template* (`assemble` with the true increments and z set to each value's
position), which gives the merged layout and where every drawn value goes; a block then draws
each trial from its own stream (`simulate.block_draws`, the same draws in the same order) and
makes the values of all its trials with array operations. A trial's stream is the template
with its values written in (`TrialBlock.fill`: one reused buffer, no stream copied per trial).
The results equal `trial_records` bit for bit (tests/test_simulate.py), so seeds give the same
sweep as before.

The realism switches (realism.py) change R and aux per trial (inflate-r, consider): a scenario
with any of them active takes the road per trial.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from leonav_runtime.common.columns import columnwise
from leonav_runtime.core import navfuncs
from leonav_runtime.gen.state_layout import AUX_F_B_SLICE
from leonav_runtime.inputs import ImuTable, LocalSensorTable, Prior, assemble
from leonav_runtime.inputs.imu import F_B_AVERAGE_S, latest_sample
from leonav_runtime.scenarios.load import mode_of
from leonav_runtime.simulation import realism, simulate


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

    def flat_positions(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where the IMU u, the z and the averaged specific force go in the stream viewed as flat
        float64 (those fields of RECORD_DTYPE are float64 at 8-byte offsets): (n, 6), (values,),
        (records, 3)."""
        if "_flat" not in self.__dict__:
            (width, rest), offsets = divmod(self.rec.dtype.itemsize, 8), self.rec.dtype.fields
            field = {name: offsets[name][1] // 8 for name in ("u", "z", "aux")}
            if rest or any(offsets[name][1] % 8 for name in field):
                raise RuntimeError(f"record dtype {self.rec.dtype}: u, z, aux expected at 8-byte offsets")
            self.__dict__["_flat"] = (
                self.imu_pos[:, None] * width + field["u"] + np.arange(6),
                self.meas_pos * width + field["z"],
                self.fb_pos[:, None] * width + field["aux"] + np.arange(AUX_F_B_SLICE.start, AUX_F_B_SLICE.stop))
        return self.__dict__["_flat"]


@dataclass
class TrialBlock:
    """Trials of one (mode, count): x0 (B, NX); params (NP,), the filter's parameters of every
    trial, or (B, NP) per trial; each trial's truth (`truth`) and record stream (RECORD_DTYPE,
    from `records(j)` or, without a copy per trial, `fill(j, buffer)`)."""

    x0: np.ndarray
    params: np.ndarray
    template: Template | None = None
    u: np.ndarray | None = None        # (B, n, 6) measured IMU increments
    z: np.ndarray | None = None        # (B, values) each trial's value vector (template.meas_src)
    f_b: np.ndarray | None = None      # (B, distinct samples, 3) averaged specific force, m/s^2 body
    errors: dict | None = None         # sensor-error truth per block (B, n+1, size) ...
    x_base: np.ndarray | None = None   # ... over this truth (n+1, NX)
    streams: np.ndarray | None = None  # (B, nrec) the streams themselves (road per trial: realism) ...
    x_true: np.ndarray | None = None   # ... and their truths (B, n+1, NX)
    trials: list | None = None         # the trials themselves when their streams differ in length
    counts: list | None = None         # each trial's front-end counts (simulate.Trial.counts)

    def truth(self, k: np.ndarray | slice = slice(None)) -> np.ndarray:
        """(B, len(k), NX): each trial's truth, sensor errors included, at IMU samples k."""
        if self.x_true is not None:
            return self.x_true[:, k]
        return simulate.with_errors(self.x_base[k], {name: v[:, k] for name, v in self.errors.items()}, len(self))

    def __len__(self) -> int:
        return self.x0.shape[0]

    def buffer(self) -> np.ndarray:
        """A stream to `fill`: the template's (everything but the drawn values)."""
        return self.streams[0].copy() if self.template is None else self.template.rec.copy()

    def fill(self, j: int, buf: np.ndarray) -> np.ndarray:
        """Trial j's stream written into `buf` (from `buffer()`; only the drawn values change)."""
        if self.template is None:
            buf[:] = self.streams[j]
            return buf
        tpl = self.template
        u_at, z_at, f_b_at = tpl.flat_positions()
        if not buf.flags.c_contiguous:
            raise ValueError("TrialBlock.fill: the buffer must be C-contiguous (from buffer())")
        flat = buf.view(np.float64)     # a scatter into flat float64 positions: ~3x the field views'
        flat[u_at] = self.u[j]
        # np.take: a gather along one axis, ~2.5x faster than the same fancy index
        flat[z_at] = np.take(self.z[j], tpl.meas_src)
        flat[f_b_at] = np.take(self.f_b[j], tpl.fb_sample, axis=0)
        return buf

    def records(self, j: int) -> np.ndarray:
        """Trial j's record stream, a new array."""
        return self.fill(j, self.buffer())


def _markers(n: int, offset: int) -> np.ndarray:
    return offset + np.arange(n, dtype=float)


def template(setup: simulate.Setup, nav: navfuncs.NavFunctions, mode: str, count: int) -> Template:
    """The layout of every trial of (mode, count), made once per setup by the road itself."""
    key = (mode, count)
    # kept on the instance, not as a field: dataclasses.replace(setup, scn=...) must not inherit it
    cache = setup.__dict__.setdefault("_block_templates", {})
    if key in cache:
        return cache[key]
    scn, parsed = setup.scn, mode_of(mode)
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


def uses_template(scn) -> bool:
    """Whether the trials of `scn` are built from the block template: not with a realism switch
    active (it changes R and aux per trial, so each trial takes the road; module doc)."""
    return not realism.active(scn)


def satellites_used(parsed) -> list:
    """The satellite observables a parsed mode uses, in the order block_draws makes their parts."""
    return [o for o in simulate.satellites.satellite_observables() if o in parsed.observables]


def trial_block(setup: simulate.Setup, mode: str, count: int, rngs: list[np.random.Generator],
                nav: navfuncs.NavFunctions) -> TrialBlock:
    """Trials of `mode` with `count` Starlink satellites, one per stream in `rngs` (the records,
    x0 and truth `simulate.trial_records` gives for each stream, module doc)."""
    scn, L = setup.scn, nav.layout
    if not uses_template(scn):
        trials = [simulate.trial_records(setup, mode, count, rng, nav) for rng in rngs]
        if len({t.records.size for t in trials}) > 1:   # e.g. epochs of detected cycle slips dropped
            return TrialBlock(np.stack([t.x0 for t in trials]), np.stack([t.params for t in trials]), trials=trials)
        return TrialBlock(np.stack([t.x0 for t in trials]), np.stack([t.params for t in trials]),
                          streams=np.stack([t.records for t in trials]), x_true=np.stack([t.x_true for t in trials]),
                          counts=[t.counts for t in trials])
    if not rngs:
        raise ValueError("trial_block: expected at least one random stream")
    tpl = template(setup, nav, mode, count)
    parsed = mode_of(mode)
    d = simulate.block_draws(setup, parsed, count, rngs, nav)
    B = len(rngs)
    values = np.concatenate([np.zeros((B, 0))] + [z for _, _, z, _ in d.parts], axis=1)
    if parsed.local_sensors:   # local sensors: the generated h at each trial's truth (their own streams)
        x_true = simulate.with_errors(setup.x_true, d.errors, B)
        local = [np.concatenate([z.T.ravel() for _, z, _ in simulate.local_values(setup, nav, rng, parsed, x, 1.0)])
                 for rng, x in zip(rngs, x_true)]
        values = np.concatenate([values, np.stack(local)], axis=1)
    u = d.u                                                           # (B, n, 6)
    dvel = u[:, :, L.U_DVEL_B_SLICE]
    dv = np.concatenate([np.zeros((B, 1, dvel.shape[2])), np.cumsum(dvel, axis=1)], axis=1)
    e, s = tpl.fb_ends, tpl.fb_starts
    f_b = np.take(dv, e, axis=1)
    f_b -= np.take(dv, s, axis=1)
    columnwise(np.divide, f_b, (tpl.tt[e] - tpl.tt[s])[:, None], f_b)
    return TrialBlock(d.x0, setup.params, tpl, u, values, f_b, d.errors, setup.x_true)
