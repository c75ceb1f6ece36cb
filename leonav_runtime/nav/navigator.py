"""The navigation loop: arriving records -> the road -> the C filter -> solutions, and faults.

`Navigator` is fed by a source (`sources.py`) in arrival order: GNSS records, groups of IMU
samples that arrived in one read (with that read's host stamp), Doppler-rate tables from the
beacon stream, and device endings. Each IMU group steps the filter at once (`stepper.LagStepper`:
the generated C loop on the batch), and solutions go to the live outputs, at most
`output_rate_hz` per second; records leaving the lag window go to `trajectory.csv`.

Faults:
- GNSS lost (its device ended, or no fix epoch for `gnss_timeout_s`): the filter goes on with
  the IMU (and the Doppler-rate when fused); the sigma grows; solutions say fix quality 6
  (dead reckoning) until fixes come back.
- IMU lost (its device ended, or no sample for `imu_timeout_s`): the filter stops predicting
  (no solutions are sent: a stale position must not look live); GNSS keeps being recorded.
- garbage bytes are skipped by the decoders and counted per device (`rejected`).
"""
from __future__ import annotations

import collections
import dataclasses
import math
import time
from pathlib import Path

import numpy as np

from leonav.hardware.session_files import LostWrites
from leonav_runtime.common.output import write_csv
from leonav_runtime.core import filter as lfilter
from leonav_runtime.inputs.corrections import LOG_COLUMNS
from leonav_runtime.core import model, navfuncs, records
from leonav_runtime.nav.outputs import COLUMNS_TEXT, Decimator, LiveOutputs, TrajectoryWriter, solution_of
from leonav_runtime.nav.road import RoadConfig, StreamingRoad
from leonav_runtime.nav.status import StatusLine, format_status
from leonav_runtime.nav.stepper import LagStepper
from leonav_runtime.replay.options import latency_estimate, replayable
from leonav_runtime.replay.timebase import utc_of

LATENCY_KEEP = 200_000        # latency samples kept for the run's percentiles (ring)
SETTLE_CHUNK_S = 0.5          # records leave the lag window (to trajectory.csv) this much at a time


@dataclasses.dataclass
class NavConfig:
    mode: str = "fix+imu"
    road: RoadConfig = dataclasses.field(default_factory=RoadConfig)
    gate_nis: float = lfilter.CHI2_1DOF_999
    lag_s: float = 3.5
    output_rate_hz: float = 10.0
    trajectory_rate_hz: float = 10.0
    gnss_timeout_s: float = 2.0
    imu_timeout_s: float = 1.0


def navigable(o) -> bool:
    """What live navigation fuses with the IMU: what a replay does (`replay.options.replayable`)
    but the raw GNSS observations (the road has no pseudorange stream)."""
    return replayable(o) and o.table != "gnss_obs"


def nav_mode(name: str) -> model.Mode:
    """The mode of --mode, or a UserInputError naming the option."""
    return model.parse_mode(name, navigable, "--mode")


def leo_streams(name: str) -> tuple[str, ...]:
    """The Starlink record streams of nav mode `name` (what needs the beacon capture)."""
    return tuple(dict.fromkeys(o.stream for o in nav_mode(name).observables if o.source == "leo"))


class Navigator:
    def __init__(self, cfg: NavConfig, out_dir: Path, outputs: LiveOutputs | None = None,
                 status: StatusLine | None = None, nav: navfuncs.NavFunctions | None = None,
                 lost: LostWrites | None = None, corrections=None, operator=None) -> None:
        """corrections: a `base.client.CorrectionsClient` (--corrections): its store goes to the road,
        its state to the status line, events and nav.json; it is started here and stopped in finish.
        operator: an `orbits.operator_folder.OperatorFolder` (--operator-ephemerides), to the road."""
        self.cfg = cfg
        cfg.road.streams = nav_mode(cfg.mode).streams
        self.nav = nav or navfuncs.NavFunctions()
        self.corrections = corrections
        self.operator = operator
        self.road = StreamingRoad(cfg.road, self.nav, corrections.store if corrections is not None else None,
                                  operator)
        self._corr_state = "waiting"
        self.outputs = outputs or LiveOutputs()
        self.status = status or StatusLine(enabled=False)
        self.out_dir = Path(out_dir)
        self.trajectory = TrajectoryWriter(self.out_dir / "trajectory.csv", self.nav, cfg.trajectory_rate_hz, lost)
        try:
            (self.out_dir / "columns.txt").write_text(COLUMNS_TEXT)
        except OSError as exc:
            if lost is None:
                raise
            lost.add(self.out_dir / "columns.txt", exc)
        self.stepper: LagStepper | None = None
        ids = self.nav.library.meas_ids
        self.fix_kinds = {int(ids[k]) for k in ("pos_e", "pos_n", "pos_u")}
        self.dr_kind = int(ids["doppler_rate"])
        self.leo_kinds = [int(ids[o.suffix]) for o in model.OBSERVABLES    # the status line's Starlink
                          if navigable(o) and o.source == "leo"]
        self.t0_mono = time.monotonic()
        self.events: list[dict] = []
        self.faults: dict[str, str] = {}          # device -> what is wrong now
        self.lost: dict[str, str] = {}            # devices that ended during the run, with the reason
        self.rejected: dict[str, dict] = {}
        self._lat = np.full(LATENCY_KEEP, np.nan)
        self._lat_n = 0
        self._recent_lat: collections.deque = collections.deque(maxlen=2000)   # (mono, latency s)
        self._dr_settled: collections.deque = collections.deque()              # (t, sat) applied, left the window
        self._out_due = Decimator(1.0 / cfg.output_rate_hz if cfg.output_rate_hz > 0 else 0.0)
        self.last_imu_stamp = math.inf
        self.last_solution = None
        if corrections is not None:
            corrections.on_event = lambda text, kind: self.event(text, kind)
            corrections.start()

    # -- events in
    def event(self, text: str, kind: str = "info") -> None:
        self.events.append({"t_run_s": round(time.monotonic() - self.t0_mono, 3), "kind": kind, "text": text})
        self.status.event(f"leonav nav: {text}")

    def on_gnss(self, rec) -> None:
        self.road.add_gnss(rec)
        self._step()

    def on_imu(self, samples: list, stamp_s: float, arrived_mono: float) -> None:
        self.last_imu_stamp = stamp_s
        if "imu" in self.faults and "imu" not in self.lost:
            self.event("IMU samples again: predicting", "recovered")
            del self.faults["imu"]
        self.road.add_imu(samples, stamp_s)
        self._step(arrived_mono)

    def on_doppler_rate(self, table) -> None:
        self.road.add_satellite_table(table)
        self._step()

    def on_carrier_phase(self, table) -> None:
        self.road.add_satellite_table(table)
        self._step()

    def device_ended(self, kind: str, reason: str) -> None:
        if kind in self.lost:
            return
        self.lost[kind] = reason
        leo = leo_streams(self.cfg.mode)
        what = {"gnss": "GNSS lost: going on with the IMU" + (" and Starlink" if leo else "") + ", sigma grows",
                "imu": "IMU lost: not predicting any more",
                "sdr": "SDR lost: no more Starlink measurements"}.get(kind, f"{kind} lost")
        self.faults[kind] = f"{kind.upper()} LOST"
        self.event(f"{what} ({reason})", "device_lost")

    # -- the filter
    def _start_filter(self) -> None:
        inp = self.road.inputs
        ekf = lfilter.EKF(inp.x0, inp.P0, inp.params, gate=self.cfg.gate_nis or None, library=self.nav.library)
        self.stepper = LagStepper(ekf, self.cfg.lag_s)
        lat, lon, h = inp.origin
        self.event(f"started at {utc_of(self.road.epoch_unix + self.road.t_start).isoformat()} "
                   f"(origin {math.degrees(lat):.7f}, {math.degrees(lon):.7f}, {h:.2f} m; mode {self.cfg.mode})",
                   "start")

    def _step(self, arrived_mono: float | None = None) -> None:
        """Run what the road has ready; publish when IMU samples arrived (`arrived_mono`: their arrival)."""
        recs = self.road.take()
        if not recs.size:
            return
        if self.stepper is None:
            self._start_filter()
        self.stepper.step(recs)
        if arrived_mono is not None and np.any(recs["kind"] == records.KIND_IMU):
            self._publish(arrived_mono)
        if self.stepper.head_t - self.stepper.window_start_t > self.cfg.lag_s + SETTLE_CHUNK_S:
            settled = self.stepper.settle()        # in chunks: one trajectory write per half second
            if settled is not None:
                self._settled(settled)

    def _settled(self, settled) -> None:
        self.trajectory.add(settled, self.road.epoch_unix, self.road.origin, self.fix_kinds, self.dr_kind)
        dr = np.isin(settled.recs["kind"], self.leo_kinds) & (settled.status == lfilter.STATUS_APPLIED)
        self._dr_settled.extend(zip(settled.recs["t"][dr].tolist(), settled.recs["sat_id"][dr].tolist()))
        while self._dr_settled and self._dr_settled[0][0] < settled.recs["t"][-1] - 10.0:
            self._dr_settled.popleft()

    def _window_counts(self, t_head: float) -> tuple[int, int, int]:
        """(fix epochs applied in the last second, Starlink records (Doppler-rate, carrier phase)
        applied in the last 10 s and their satellites), from the lag window and the records that left it."""
        recs, status = self.stepper.window()
        ok = status == lfilter.STATUS_APPLIED
        t = recs["t"]
        n_fix = int(np.sum(ok & (t > t_head - 1.0) & np.isin(recs["kind"], list(self.fix_kinds)))) // 3
        dr = ok & np.isin(recs["kind"], self.leo_kinds) & (t > t_head - 10.0)
        old = [sat for (t_dr, sat) in self._dr_settled if t_dr > t_head - 10.0]
        return n_fix, int(dr.sum()) + len(old), len(set(recs["sat_id"][dr].tolist()) | set(old))

    def gnss_ok(self) -> bool:
        return "gnss" not in self.faults

    def _publish(self, arrived_mono: float) -> None:
        t_head = self.stepper.head_t
        if self._out_due(t_head, self.road.imu_dt):
            x, P = self.stepper.head()
            n_fix, n_dr, n_sats = self._window_counts(t_head)   # Starlink: satellites over 10 s (they come late)
            fused_fix = "fix" in self.cfg.road.streams
            quality = 1 if (fused_fix and self.gnss_ok()) or (not fused_fix and n_dr) else 6
            mode = self.cfg.mode if self.gnss_ok() or not fused_fix else self.cfg.mode.replace("fix+", "") + " (GNSS lost)"
            sol = solution_of(x, np.diag(P), utc_of(self.road.epoch_unix + t_head), self.road.origin, self.nav,
                              mode=mode, n_gnss=n_fix, n_leo=n_sats, fix_quality=quality, latency_s=math.nan)
            sol = dataclasses.replace(sol, latency_s=time.monotonic() - arrived_mono)
            self.outputs.send(sol)
            self.last_solution = sol
        lat = time.monotonic() - arrived_mono
        self._lat[self._lat_n % LATENCY_KEEP] = lat
        self._lat_n += 1
        self._recent_lat.append((time.monotonic(), lat))

    # -- housekeeping
    def tick(self, now_mono: float | None = None, rejected: dict | None = None) -> None:
        """Timeouts, fix epochs that waited for GST, the status line (call every ~50 ms)."""
        now = time.monotonic() if now_mono is None else now_mono
        if rejected is not None:
            self.rejected = rejected
        self.road.poll(now)
        self._step()
        if self.road.started:
            stale = now - self.road.last_fix_mono
            if "gnss" not in self.faults and stale > self.cfg.gnss_timeout_s:
                self.faults["gnss"] = f"NO GNSS FIX {stale:.0f} s"
                self.event(f"no GNSS fix for {self.cfg.gnss_timeout_s:g} s: dead reckoning, sigma grows", "gnss_lost")
            elif "gnss" in self.faults and "gnss" not in self.lost and stale < self.cfg.gnss_timeout_s:
                del self.faults["gnss"]
                self.event("GNSS fixes again", "recovered")
            idle = now - self.last_imu_stamp
            if "imu" not in self.faults and idle > self.cfg.imu_timeout_s:
                self.faults["imu"] = "IMU SILENT: not predicting"
                self.event(f"no IMU sample for {self.cfg.imu_timeout_s:g} s: not predicting", "imu_lost")
        if self.corrections is not None and self.corrections.store.state != self._corr_state:
            self._corr_state = self.corrections.store.state
            self.event({"applied": "corrections applied to the Doppler-rate",
                        "fallback": "no usable corrections: Doppler-rate uncorrected (fallback)"}.get(
                self._corr_state, self._corr_state), f"corrections_{self._corr_state}")
        if self.status.due():
            self.status.update(format_status(self.snapshot()), force=True)

    def latency_percentiles(self, recent_s: float | None = None) -> tuple[float, float] | None:
        if recent_s is not None:
            now = time.monotonic()
            v = np.array([lt for (m, lt) in self._recent_lat if now - m <= recent_s])
        else:
            v = self._lat[:min(self._lat_n, LATENCY_KEEP)]
        if v.size == 0:
            return None
        return float(np.percentile(v, 50) * 1e3), float(np.percentile(v, 99) * 1e3)

    def junk_bytes(self) -> int:
        return int(sum(d.get("junk_bytes", 0) for d in self.rejected.values()))

    def snapshot(self) -> dict:
        s = {"elapsed_s": time.monotonic() - self.t0_mono, "started": self.stepper is not None,
             "junk_bytes": self.junk_bytes(), "faults": ", ".join(self.faults.values())}
        if self.stepper is None:
            s["waiting_for"] = self.road.waiting_for()
            return s
        L = self.nav.layout
        pd = np.diag(self.stepper.head()[1])
        sp = np.sqrt(np.maximum(pd[L.DX_DP_SLICE], 0))
        n_fix, n_dr, n_sats = self._window_counts(self.stepper.head_t)
        mode = self.cfg.mode if self.gnss_ok() or "fix" not in self.cfg.road.streams else "dead reckoning"
        return s | {"mode": mode, "sigma_3d_m": float(np.linalg.norm(sp)), "sigma_h_m": float(np.hypot(sp[0], sp[1])),
                    "gnss_1s": n_fix, "leo_10s": n_dr, "leo_sats": n_sats,
                    "latency_ms": self.latency_percentiles(1.0),
                    "corrections": None if self.corrections is None else self.corrections.status_text()}

    def _write_corrections_log(self) -> None:
        """corrections.csv: every Doppler-rate measurement released, the correction it took and its age."""
        try:
            write_csv(self.out_dir / "corrections.csv", LOG_COLUMNS, self.corrections.store.log_rows())
        except OSError as exc:
            self.event(f"corrections.csv not written ({exc.strerror or exc})", "lost_write")

    def finish(self) -> dict:
        """Apply what can still be applied, settle every record, close the trajectory; returns a summary."""
        self.road.flush()
        self._step()
        if self.stepper is not None:
            settled = self.stepper.settle_all()
            if settled is not None:
                self._settled(settled)
        self.trajectory.close()
        corrections = None
        if self.corrections is not None:
            self.corrections.stop()
            corrections = self.corrections.describe()
            self._write_corrections_log()
        r = self.road
        lat = self.latency_percentiles()
        out = {
            "mode": self.cfg.mode, "started": self.stepper is not None,
            "epoch_utc": r.epoch_utc, "t_start_s": r.t_start if r.started else None,
            "origin_deg": None if r.origin is None else [math.degrees(r.origin[0]), math.degrees(r.origin[1]),
                                                         r.origin[2]],
            "trajectory_rows": self.trajectory.rows,
            "latency_ms": None if lat is None else {"p50": lat[0], "p99": lat[1], "samples": self._lat_n},
            "filter": None if self.stepper is None else dict(self.stepper.counts),
            "road": dict(r.counts), "pending_measurements_at_end": r.pending,
            "time_map": r.tmap.describe(), "imu_timing": dataclasses.asdict(r.timing.counts),
            "imu_period_s": r.timing.period, "fix_epochs": dict(r.assembler.counts),
            "rejected": self.rejected, "devices_lost": self.lost, "events": self.events,
            "notes": sorted(r.notes) + ([] if r.inputs is None else list(r.inputs.notes)),
            "initialization": None if r.inputs is None else r.inputs.init,
        }
        if corrections is not None:
            out["corrections"] = corrections
        if self.operator is not None:
            op = self.operator
            out["operator_ephemerides"] = {"folder": str(op.folder), **op.counts,
                                           "refused": [f"{f}: {why}" for f, why in op.set.rejected]}
        if self.stepper is not None and r.cfg.gnss_latency_s == "estimate":
            x, P = self.stepper.head()
            L = self.nav.layout
            out["fix_latency_s"] = latency_estimate(x, np.diag(P), L)
        if self.last_solution is not None:
            out["last_solution"] = {"utc": self.last_solution.utc, "lat_deg": self.last_solution.lat_deg,
                                    "lon_deg": self.last_solution.lon_deg, "h_m": self.last_solution.h_m,
                                    "sigma_enu_m": self.last_solution.sigma_enu_m}
        return out
