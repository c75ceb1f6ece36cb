"""What `leonav nav` writes: live solutions (NMEA over TCP / a pty, MAVLink, JSON lines) and the
trajectory file, flushed as it goes so a stopped or killed run leaves readable files.

- `solution_of`: the filter state -> `live.NavSolution` (geodetic position, ENU velocity, Euler
  angles from the generated `leonav_euler_from_q`, 1-sigma from the covariance diagonal).
- `LiveOutputs`: the sinks of `leonav_runtime.nav.sinks` (`TcpBroadcastServer`, `PtyOutput`,
  `MavlinkOutput`) plus a JSON-lines file; a sink that fails is closed and counted, never fatal
  (a JSON line that cannot be written, e.g. on a full disk, is counted in `lost` and the file kept).
- `TrajectoryWriter`: `trajectory.csv` (columns in `TRAJECTORY_COLUMNS`, described in
  `COLUMNS_TEXT`) from the records as they leave the filter's lag window, i.e. after every
  measurement of that time was applied: the rows a replay of the same records gives. Rows that
  cannot be written (a full disk) are counted in `lost` (`LostWrites`); the file ends on a whole row.
"""
from __future__ import annotations

import contextlib
import csv
import datetime as _dt
import errno
import io
import math
from pathlib import Path

import numpy as np

from leonav.hardware.session_files import LostWrites, RecordFile
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.core import navfuncs, records
from leonav_runtime.core.filter import STATUS_APPLIED
from leonav_runtime.orbits import geometry
from leonav_runtime.nav.sinks import nmea_out
from leonav_runtime.nav.sinks.servers import PtyOutput, TcpBroadcastServer
from leonav_runtime.nav.sinks.solution import NavSolution

TRAJECTORY_COLUMNS = [
    "utc_unix_s", "utc", "t_s", "lat_deg", "lon_deg", "h_m", "x_ecef_m", "y_ecef_m", "z_ecef_m",
    "p_e_m", "p_n_m", "p_u_m", "v_e_mps", "v_n_mps", "v_u_mps", "roll_deg", "pitch_deg", "yaw_deg",
    "sigma_p_e_m", "sigma_p_n_m", "sigma_p_u_m", "sigma_v_e_mps", "sigma_v_n_mps", "sigma_v_u_mps",
    "sigma_roll_deg", "sigma_pitch_deg", "sigma_yaw_deg", "gnss_fixes_1s", "doppler_rate_1s",
]
COLUMNS_TEXT = (
    "trajectory.csv: one row per IMU sample, at most --trajectory-rate per second, the filter after every record "
    "of that time (the same rows a replay of these records gives).\n"
    "utc_unix_s [s POSIX], utc [ISO 8601]; t_s [s since nav.json epoch_utc]; lat_deg, lon_deg [deg WGS84], "
    "h_m [m above the ellipsoid]; x/y/z_ecef_m [m, WGS84 ECEF]; p_e/n/u_m [m, ENU at nav.json origin]; "
    "v_e/n/u_mps [m/s, ENU]; roll/pitch/yaw_deg [deg, Z-Y-X, yaw from East towards North]; sigma_* "
    "[1-sigma from the filter covariance: position m, velocity m/s, attitude deg (body-frame error "
    "angles)]; gnss_fixes_1s, doppler_rate_1s [measurements applied in the second up to this row].\n")


def _geodetic(p_enu: np.ndarray, origin) -> tuple[float, float, float, np.ndarray]:
    lat0, lon0, h0 = origin
    r = geometry.enu_to_ecef(np.asarray(p_enu, float), geometry.geodetic_to_ecef(lat0, lon0, h0), lat0, lon0)
    lat, lon, h = geometry.ecef_to_geodetic(r)
    return float(lat), float(lon), float(h), np.asarray(r, float).reshape(3)


def solution_of(x: np.ndarray, P_diag: np.ndarray, utc: _dt.datetime, origin, nav: navfuncs.NavFunctions, *,
                mode: str, n_gnss: int, n_leo: int, fix_quality: int, latency_s: float) -> NavSolution:
    L = nav.layout
    lat, lon, h, _ = _geodetic(x[L.X_P_ENU_SLICE], origin)
    rpy = nav.euler_from_quat(x[L.X_Q_NB_SLICE]).reshape(-1)
    sig = np.sqrt(np.maximum(P_diag, 0.0))
    return NavSolution(
        utc=utc, lat_rad=lat, lon_rad=lon, h_m=h, v_enu_mps=tuple(float(v) for v in x[L.X_V_ENU_SLICE]),
        rpy_rad=tuple(float(a) for a in rpy), sigma_enu_m=tuple(float(s) for s in sig[L.DX_DP_SLICE]),
        sigma_v_enu_mps=tuple(float(s) for s in sig[L.DX_DV_SLICE]),
        yaw_sigma_rad=float(sig[L.DX_DTHETA_SLICE][2]), mode=mode, n_gnss=n_gnss, n_leo=n_leo,
        fix_quality=fix_quality, latency_s=latency_s)


@contextlib.contextmanager
def _named(what: str, hint: str = ""):
    """An OSError opening an output -> a one-line UserInputError naming that output."""
    try:
        yield
    except OSError as exc:
        raise UserInputError(f"{what} ({exc.strerror or exc}){hint}") from None


def _listen(host: str, port: int, max_clients: int | None) -> TcpBroadcastServer:
    """The NMEA TCP server, bound but not yet accepting; a taken port is said so in one line."""
    try:
        return TcpBroadcastServer(host, port, start=False,
                                  **({} if max_clients is None else {"max_clients": max_clients}))
    except OSError as exc:
        if exc.errno == errno.EADDRINUSE:
            raise UserInputError(f"--nmea-port {port}: port {port} on {host} is taken (another program, or another "
                                 "`leonav nav`, listens on it); give --nmea-port auto (a free port, printed at "
                                 "the start) or --nmea-port 0 (no NMEA server)") from None
        raise UserInputError(f"--nmea-port {port} on {host}: cannot listen ({exc.strerror or exc}); expected a "
                             "free port and an address of this machine (--nmea-host)") from None


class LiveOutputs:
    """NMEA (TCP server and/or pty), MAVLink and JSON lines for each solution. The TCP server
    accepts clients only after `start()`: `leonav nav` calls it once everything is imported and
    open (under descriptor exhaustion a lazy import or a first file open would fail)."""

    def __init__(self, tcp: tuple[str, int] | None = None, pty_link: str | None = None, mavlink: str | None = None,
                 json_path: Path | None = None, max_clients: int | None = None,
                 lost: LostWrites | None = None) -> None:
        self.sinks: dict[str, object] = {}
        self.errors: dict[str, str] = {}
        self.counts = {"solutions": 0}
        try:
            if tcp is not None:
                self.sinks["tcp"] = _listen(tcp[0], tcp[1], max_clients)
            if pty_link:
                with _named(f"--nmea-pty {pty_link}: cannot open a pty"):   # PtyOutput names what is at the path
                    self.sinks["pty"] = PtyOutput(pty_link)
            if mavlink:
                from leonav_runtime.nav.sinks.mavlink_out import MavlinkOutput

                with _named(f"--mavlink {mavlink}: cannot open"):
                    self.sinks["mavlink"] = MavlinkOutput(mavlink)
            if json_path is not None:
                with _named(f"{json_path}: cannot write"):
                    self.sinks["json"] = RecordFile(json_path, lost)
        except Exception:
            self.close()
            raise

    def start(self) -> None:
        """Start serving (the TCP server accepts from now on)."""
        if "tcp" in self.sinks:
            self.sinks["tcp"].start()

    @property
    def tcp_address(self) -> tuple[str, int] | None:
        s = self.sinks.get("tcp")
        return tuple(s.address) if s is not None else None

    @property
    def pty_device(self) -> str | None:
        s = self.sinks.get("pty")
        return s.device if s is not None else None

    def send(self, sol: NavSolution) -> None:
        self.counts["solutions"] += 1
        nmea = None
        for name, sink in list(self.sinks.items()):
            try:
                if name in ("tcp", "pty"):
                    nmea = nmea or nmea_out.sentences(sol)
                    sink.send(nmea)
                elif name == "mavlink":
                    sink.send(sol)
                else:
                    sink.write(sol.json_line().encode())
            except Exception as exc:   # an output must never stop the navigator
                self.errors[name] = f"{type(exc).__name__}: {exc}"
                self._close_one(name)

    def _close_one(self, name: str) -> None:
        sink = self.sinks.pop(name, None)
        if sink is not None:
            try:
                sink.close()
            except Exception:
                pass

    def close(self) -> dict:
        """Flush and close every sink; returns their counts."""
        report = {"solutions": self.counts["solutions"], "errors": dict(self.errors)}
        for name in list(self.sinks):
            sink = self.sinks[name]
            if hasattr(sink, "counts"):
                report[name] = dict(sink.counts)
            self._close_one(name)
        return report


class Decimator:
    """Every sample, or one per `period` s: a sample is due when it is at least `period` minus half
    its own interval after the last one taken (a grid of fixed slots would skip or double samples
    whose times straddle its boundaries)."""

    def __init__(self, period: float) -> None:
        self.period = period
        self.last = -math.inf

    def __call__(self, t: float, dt: float) -> bool:
        if t < self.last + self.period - 0.5 * dt:
            return False
        self.last = t
        return True


class TrajectoryWriter:
    """trajectory.csv rows from settled records (module doc), at most `rate_hz` per second."""

    def __init__(self, path: Path, nav: navfuncs.NavFunctions, rate_hz: float = 10.0,
                 lost: LostWrites | None = None) -> None:
        self.path = Path(path)
        self.nav = nav
        self.period = 1.0 / rate_hz if rate_hz > 0 else 0.0
        self._fh = RecordFile(self.path, lost)
        self._buf = io.StringIO()
        self._w = csv.writer(self._buf)
        self._write([TRAJECTORY_COLUMNS])
        self.rows = 0                 # rows in the file (those that could not be written are in `lost`)
        self._due = Decimator(self.period)
        self._meas_t: list[tuple[float, int]] = []    # (t, kind) of applied measurements, last second

    def add(self, settled, epoch_unix: float, origin, fix_kinds: set[int], dr_kind: int) -> None:
        L = self.nav.layout
        recs, t = settled.recs, settled.recs["t"]
        applied = settled.status == STATUS_APPLIED
        for t_m, k in zip(t[applied], recs["kind"][applied]):
            self._meas_t.append((float(t_m), int(k)))
        imu = np.flatnonzero(recs["kind"] == records.KIND_IMU)
        if imu.size == 0:
            return
        last = np.searchsorted(t, t[imu], side="right") - 1      # after every record of that time
        rows = []
        for i, j in zip(imu, last):
            if not self._due(float(t[i]), float(recs["dt"][i])):
                continue
            x, pd = settled.x[j], settled.P_diag[j]
            lat, lon, h, r = _geodetic(x[L.X_P_ENU_SLICE], origin)
            rpy = np.degrees(self.nav.euler_from_quat(x[L.X_Q_NB_SLICE]).reshape(-1))
            sig = np.sqrt(np.maximum(pd, 0.0))
            self._meas_t = [m for m in self._meas_t if m[0] > t[i] - 1.0]
            n_fix = sum(1 for m in self._meas_t if m[0] <= t[i] and m[1] in fix_kinds) // max(len(fix_kinds), 1)
            n_dr = sum(1 for m in self._meas_t if m[0] <= t[i] and m[1] == dr_kind)
            utc = epoch_unix + float(t[i])
            nums = [utc, None, t[i], math.degrees(lat), math.degrees(lon), h, *r, *x[L.X_P_ENU_SLICE],
                    *x[L.X_V_ENU_SLICE], *rpy, *sig[L.DX_DP_SLICE], *sig[L.DX_DV_SLICE],
                    *np.degrees(sig[L.DX_DTHETA_SLICE])]
            row = [repr(float(v)) if v is not None else None for v in nums] + [n_fix, n_dr]
            row[1] = _dt.datetime.fromtimestamp(utc, _dt.timezone.utc).isoformat()
            rows.append(row)
        if rows and self._write(rows):
            self.rows += len(rows)

    def _write(self, rows: list) -> bool:
        """Write `rows` at once (whole, or none of them: `RecordFile`)."""
        self._w.writerows(rows)
        text = self._buf.getvalue()
        self._buf.seek(0)
        self._buf.truncate()
        return self._fh.write(text.encode("utf-8"), n_records=len(rows))

    def close(self) -> None:
        self._fh.close()
