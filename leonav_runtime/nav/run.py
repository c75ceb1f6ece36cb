"""One run of `leonav nav`: a source, the navigator, the outputs, signals -> files and an exit code.

Exit codes (also in nav.json `exit_code` and `leonav nav --help`):
  0    the run ended as asked (--seconds elapsed, or the played-back session ended) and navigated;
       also when output records could not be written (a full disk, an I/O error): navigation and the
       live outputs went on, nav.json `files_complete` is false and `lost_writes` counts per file what
       is missing (`lost_write_errors`: the first error of each), and stderr says so. Not a code of
       its own: the CLI marks a folder of a non-zero run FAILED ("failed before it finished", untrue
       here), and on a disk still full that marker cannot be written either, which would turn the
       code into a generic I/O error (3) exactly when it matters
  1    it never navigated: no GNSS time tag, no usable fix or no IMU data (outputs still written)
  2    bad arguments or input files (the CLI's convention for every command), OUT locked by another
       run (`out_lock`: one writer per folder), --nmea-pty PATH holding something not ours
  3    a device disappeared during the run (the filter went on with the rest; see nav.json)
  130  interrupted by SIGINT (Ctrl-C)
  143  stopped by SIGTERM (systemd stop): every output flushed, as for 0
The NMEA TCP server binds its port first (a taken port fails before anything is written) and accepts
clients only once the devices are open and `preload` has imported and opened what the run needs.
SIGINT and SIGTERM only set a flag: the loop sees it within 50 ms, then every output is flushed
and closed and session.json, trajectory.csv and nav.json are complete.

A full disk never stops a run: every file writer shares one `LostWrites` that counts what could
not be written. `RESERVE_BYTES` are set aside in OUT at the start (a preallocated file) and freed
at the end, half before session.json and the last trajectory rows, the rest before nav.json, so
those small files still fit on a disk that filled up during the run; if nav.json does not fit,
one stderr line says so and what was lost.
"""
from __future__ import annotations

import copy
import dataclasses
import datetime as _dt
import functools
import os
import signal
import sys
import threading
from pathlib import Path
from typing import Callable

from leonav.hardware.session_files import LostWrites
from leonav_runtime.core import navfuncs
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.nav.navigator import Navigator, NavConfig
from leonav_runtime.nav.out_lock import lock_out_dir
from leonav_runtime.nav.outputs import LiveOutputs
from leonav_runtime.nav.status import StatusLine
from leonav_runtime.common.output import write_json
from leonav_runtime.common.provenance import provenance

EXIT_OK, EXIT_NEVER_NAVIGATED, EXIT_USAGE, EXIT_DEVICE_LOST = 0, 1, 2, 3
EXIT_SIGINT, EXIT_SIGTERM = 130, 143
RESERVE_NAME = ".leonav-nav.reserve"
RESERVE_BYTES = 64 * 1024     # room kept for session.json and nav.json (a few KB each, plus temporary copies)
EXIT_CODES = {EXIT_OK: "ended as asked and navigated", EXIT_NEVER_NAVIGATED: "never navigated (no time tag, fix or IMU)",
              EXIT_USAGE: "bad arguments or input", EXIT_DEVICE_LOST: "a device disappeared during the run",
              EXIT_SIGINT: "interrupted (SIGINT)", EXIT_SIGTERM: "stopped (SIGTERM)"}


@dataclasses.dataclass
class NavOptions:
    out_dir: Path
    nav: NavConfig
    session: Path | None = None           # --from SESSION
    realtime: bool = False
    gnss: str | None = None
    imu: str | None = None
    sdr_index: int | None = None
    gnss_baud: int = 38400
    imu_baud: int = 9600
    configure: bool = False
    sdr_settings: object = None
    seconds: float | None = None
    record: bool = True
    tcp: tuple[str, int] | None = ("127.0.0.1", 10110)
    nmea_max_clients: int | None = None   # None: sinks.servers.MAX_CLIENTS
    pty_link: str | None = None
    mavlink: str | None = None
    json_lines: bool = True
    status: bool | None = None            # None: on when stderr is a terminal (else a line every 10 s)
    tle_files: tuple = ()
    corrections: tuple[str, int] | None = None     # --corrections HOST:PORT
    corrections_max_age_s: float | None = None     # None: inputs.corrections.DEFAULT_MAX_AGE_S
    operator_ephemerides: str | None = None        # --operator-ephemerides DIR (docs/ephemerides.md)


class _Signals:
    """SIGINT/SIGTERM -> a flag (main thread only; elsewhere `request` is the way to stop)."""

    def __init__(self) -> None:
        self.received: int | None = None
        self._old: dict = {}

    def request(self, signum: int = signal.SIGINT) -> None:
        if self.received is None:
            self.received = signum

    def __enter__(self) -> "_Signals":
        if threading.current_thread() is threading.main_thread():
            for s in (signal.SIGINT, signal.SIGTERM):
                self._old[s] = signal.signal(s, lambda signum, frame: self.request(signum))
        return self

    def __exit__(self, *exc) -> None:
        for s, h in self._old.items():
            signal.signal(s, h)


class _Reserve:
    """Disk space set aside for the end of the run (module doc); every step is best-effort."""

    def __init__(self, folder: Path, size: int = RESERVE_BYTES) -> None:
        self.path = folder / RESERVE_NAME
        try:
            fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_CLOEXEC, 0o600)
            try:
                os.posix_fallocate(fd, 0, size)
            finally:
                os.close(fd)
        except (OSError, AttributeError):   # a full disk already, or no fallocate here: no reserve
            self.shrink(0)

    def shrink(self, size: int) -> None:
        """Free all but `size` bytes (0: remove the file)."""
        try:
            if size > 0:
                os.truncate(self.path, size)
            else:
                os.unlink(self.path)
        except OSError:
            pass


def _source(opts: NavOptions, record_dir: Path | None, beacons, lost: LostWrites):
    from leonav_runtime.nav import sources

    if opts.session is not None and not opts.realtime:
        return sources.FastPlayback(opts.session, record_dir, beacons, lost)
    if opts.session is not None:
        return _realtime_playback(opts, record_dir, beacons, lost)
    if not (opts.gnss or opts.imu):
        raise UserInputError("nav: give --gnss PORT and --imu PORT (live devices) or --from SESSION")
    return sources.LiveSource(record_dir, opts.gnss, opts.imu, opts.sdr_index, opts.gnss_baud, opts.imu_baud,
                              opts.configure, opts.sdr_settings, beacons=beacons, lost=lost)


def _realtime_playback(opts: NavOptions, record_dir: Path, beacons, lost: LostWrites):
    from leonav.hardware.sdr.capture import SdrSettings
    from leonav_runtime.nav import sources
    from leonav_runtime.nav.beacon_feed import capture_meta

    folder = Path(opts.session)
    t0 = sources.session_start_mono(folder)
    ptys = [sources.PacedPty(sources.chunk_events(folder, name, t0)) for name in ("gnss", "imu")]
    info = sources.read_session_info(folder)
    sdr = {}
    if beacons is not None:
        m = capture_meta(folder / "sdr.sigmf-meta")
        delay = float(m["t_mono_start_s"]) - t0 if m.get("t_mono_start_s") is not None else 0.0
        sdr = {"sdr_index": 0, "sdr_factory": lambda index: sources.FileRtlSdr(folder / "sdr.cu8", delay),
               "sdr_settings": SdrSettings(rf_center_hz=m["rf_center_hz"], lnb_lo_hz=m["lnb_lo_hz"],
                                           sample_rate_hz=m["sample_rate_hz"], gain_db=m["gain_db"])}
    return sources.LiveSource(record_dir, ptys[0].path, ptys[1].path, gnss_baud=sources._baud(info, "gnss") or 38400,
                              imu_baud=sources._baud(info, "imu") or 9600, playback=ptys, beacons=beacons,
                              lost=lost, **sdr)


def _beacons(opts: NavOptions, record_dir: Path | None, operator=None):
    """(BeaconFeed or None, f_c Hz, where f_c came from) for the mode and the source; operator: the
    `OperatorFolder` of --operator-ephemerides, or None."""
    from leonav_runtime.gen.constants import STARLINK_BEACON_HZ
    from leonav_runtime.nav.beacon_feed import BeaconFeed, capture_meta, carrier
    from leonav_runtime.nav.beacon_process import BeaconProcess
    from leonav_runtime.orbits.elements import load_element_files
    from leonav_runtime.nav.navigator import leo_streams

    default = (None, STARLINK_BEACON_HZ, "default (no Starlink capture)")
    streams = leo_streams(opts.nav.mode)
    if not streams:
        return default
    phase = "carrier_phase" in streams     # the tones' carrier is tracked only for a phase mode
    elements = load_element_files(opts.tle_files)     # checked here: a bad file is a clear error at once
    floor = opts.nav.road.doppler_rate_sigma_floor_hz_s
    if opts.session is not None:
        meta_path = Path(opts.session) / "sdr.sigmf-meta"
        if not meta_path.exists() or not (Path(opts.session) / "sdr.cu8").exists():
            raise UserInputError(f"--mode {opts.nav.mode}: {opts.session} has no sdr.cu8 + sdr.sigmf-meta")
        meta = capture_meta(meta_path)
        f_c, src = carrier(meta["rf_center_hz"])
        if not opts.realtime:
            return BeaconFeed(Path(opts.session) / "sdr.cu8", meta, f_c, elements, floor, operator, phase), f_c, src
        return BeaconProcess(record_dir / "sdr.cu8", f_c, opts.tle_files, floor, operator, phase), f_c, src
    if opts.sdr_index is None:
        raise UserInputError(f"--mode {opts.nav.mode}: needs --sdr INDEX (the Starlink capture)")
    f_c, src = carrier(opts.sdr_settings.rf_center_hz)
    return BeaconProcess(record_dir / "sdr.cu8", f_c, opts.tle_files, floor, operator, phase), f_c, src


def preload(opts: NavOptions, beacons) -> dict:
    """Import and open now what the run would otherwise load on first use, once clients are served:
    with the descriptors exhausted (a client storm) a lazy import or a first file open fails. Returns
    nav.json's provenance (it reads package metadata), computed here for the same reason. What is
    loaded here was found by auditing runs; tests/test_nav_load.py and test_nav_playback_end.py fail
    on any module imported or file first opened once the NMEA server accepts."""
    import _strptime  # noqa: F401  (datetime.strptime imports it on its first call)

    _dt.datetime.strptime("2026-02-23", "%Y-%m-%d")     # and reads the locale's time names once
    if opts.mavlink:
        import encodings.idna  # noqa: F401  (the first send to a host name encodes it)
    import numpy.ma  # noqa: F401  (np.median and np.unique import it on their first call)

    if beacons is None:
        return provenance()
    from leonav_runtime.beacons.row_fft import row_fft_function
    row_fft_function()    # the STFT's FFT extension is loaded from its file on the first transform
    if opts.operator_ephemerides:   # the road's consider term and the states from the files
        import leonav_runtime.inputs.consider  # noqa: F401
        import leonav_runtime.orbits.operator_consider  # noqa: F401
        import leonav_runtime.orbits.operator_states  # noqa: F401
    if opts.session is not None and not opts.realtime:   # fast playback: the beacon stream runs in this
        from leonav_runtime.orbits import eop            # process, and its predictions read the EOP table

        eop.default_table()     # a missing or bad table is an error now rather than in the middle of the run
        if not opts.tle_files:      # the built-in Starlink set is made once the road starts, parsed in
            from leonav_runtime.orbits import element_cache  # full: the element cache would open files
            from leonav_runtime.simulation import session_synth  # noqa: F401

            element_cache.turn_off_in_this_process()
    else:       # the beacon process is spawned in the run; an SDR thread records the capture and
        import multiprocessing.popen_spawn_posix  # noqa: F401  (writes its SigMF metadata at the start and end)
        import mmap  # noqa: F401  (numpy.memmap imports it on first use: sigmf maps the data file)

        import sigmf.schema

        if not hasattr(sigmf.schema.get_schema, "cache_info"):   # sigmf reads its schema file on every
            sigmf.schema.get_schema = _copied(functools.lru_cache(sigmf.schema.get_schema))  # file: once here
        sigmf.schema.get_schema(sigmf.__specification__)     # the call SigMFFile makes
    return provenance()


def _copied(cached: Callable) -> Callable:
    """`cached` returning a fresh deep copy each call (callers may change what they get)."""
    @functools.wraps(cached)
    def call(*args, **kwargs):
        return copy.deepcopy(cached(*args, **kwargs))
    call.cache_info = cached.cache_info
    return call


def session_bauds(opts: NavOptions) -> tuple[int | None, int | None]:
    if opts.session is None:
        return opts.gnss_baud, opts.imu_baud
    from leonav_runtime.nav.sources import _baud, read_session_info

    info = read_session_info(Path(opts.session))
    return _baud(info, "gnss"), _baud(info, "imu")


def run_nav(opts: NavOptions, on_started: Callable[[], None] | None = None,
            signals: _Signals | None = None, nav: navfuncs.NavFunctions | None = None) -> dict:
    """Run to the end; returns nav.json's content (with `exit_code`). OUT is locked for the whole
    run (`out_lock`): a second run on the same OUT is refused before it writes anything."""
    out = Path(opts.out_dir)
    with lock_out_dir(out):
        reserve = _Reserve(out)
        try:
            return _run_locked(opts, out, on_started, signals, nav, reserve)
        finally:
            reserve.shrink(0)


def _run_locked(opts: NavOptions, out: Path, on_started: Callable[[], None] | None,
                signals: _Signals | None, nav: navfuncs.NavFunctions | None, reserve: _Reserve) -> dict:
    record_dir = out / "session" if opts.record or (opts.session is None or opts.realtime) else None
    cfg = opts.nav
    cfg.road.gnss_baud, cfg.road.imu_baud = session_bauds(opts)
    signals = signals or _Signals()
    status = StatusLine(enabled=True if opts.status is None else opts.status)
    if opts.status is None and not status.tty:
        status.refresh_s = 10.0
    lost = LostWrites(out)
    outputs = LiveOutputs(opts.tcp, opts.pty_link, opts.mavlink,      # each failure names its option
                          out / "solutions.jsonl" if opts.json_lines else None, opts.nmea_max_clients, lost)
    navigator = source = prov = None
    tcp_address = outputs.tcp_address       # the port taken (--nmea-port auto: the free one chosen)
    reason, session_info, beacons, f_c_source = "error", {}, None, ""
    started_utc = _dt.datetime.now(_dt.timezone.utc)
    try:
        operator = _operator(opts)
        beacons, cfg.road.f_c_hz, f_c_source = _beacons(opts, record_dir, operator)
        # the devices first: one that cannot be opened stops the run before any output file is written
        source = _source(opts, record_dir, beacons, lost)
        navigator = Navigator(cfg, out, outputs, status, nav, lost, corrections=_corrections(opts),
                              operator=operator)
        prov = preload(opts, beacons)
        outputs.start()     # serving from here on: nothing more is imported or opened for the first time
        if opts.tcp is not None and opts.tcp[1] == 0 and outputs.tcp_address:    # --nmea-port auto
            print(f"leonav nav: NMEA server on tcp://{outputs.tcp_address[0]}:{outputs.tcp_address[1]}", flush=True)
        where = [f"NMEA tcp://{outputs.tcp_address[0]}:{outputs.tcp_address[1]}" if outputs.tcp_address else "",
                 f"NMEA pty {opts.pty_link} -> {outputs.pty_device}" if outputs.pty_device else "",
                 f"MAVLink {opts.mavlink}" if opts.mavlink else ""]
        status.event(f"leonav nav: {cfg.mode}, writing {out}" + "".join(f"; {w}" for w in where if w))
        with signals:
            reason = source.run(navigator, opts.seconds, on_started=on_started,
                                should_stop=lambda: signals.received is not None)
    finally:
        prev = {s: signal.signal(s, signal.SIG_IGN) for s in (signal.SIGINT, signal.SIGTERM)} \
            if threading.current_thread() is threading.main_thread() else {}
        try:
            state = {signal.SIGINT: "interrupted", signal.SIGTERM: "terminated"}.get(signals.received,
                                                                                    "complete" if reason != "error"
                                                                                    else "error")
            reserve.shrink(RESERVE_BYTES // 2)      # room for session.json and the last trajectory rows
            if source is not None:
                session_info = source.stop(state)
            summary = navigator.finish() if navigator is not None else {}
            outputs_report = outputs.close()
            status.close()
        finally:
            for s, h in prev.items():
                signal.signal(s, h)
    code = exit_code(signals.received, summary, session_info)
    result = {"exit_code": code, "exit_meaning": EXIT_CODES[code], "end_reason": reason, "status": state,
              "started_utc": started_utc, "source": _describe_source(opts), "outputs": outputs_report,
              "session_folder": str(record_dir) if record_dir else None,
              "session_status": session_info.get("status"), "exit_codes": EXIT_CODES,
              "f_c_hz": cfg.road.f_c_hz, "f_c_source": f_c_source,
              "beacons": beacons.summary() if beacons is not None else None} | summary
    result |= {"files_complete": not lost.total(), "lost_writes": dict(lost.counts),
               "lost_write_errors": dict(lost.first_error)}
    if tcp_address:
        result["nmea_tcp"] = f"{tcp_address[0]}:{tcp_address[1]}"
    reserve.shrink(0)
    try:
        write_json(out / "nav.json", {"provenance": prov if prov is not None else provenance(), **result})
    except OSError as exc:      # even the summary did not fit: say so, and what was lost, in one line
        lost.add(out / "nav.json", exc)
        result |= {"files_complete": False, "lost_writes": dict(lost.counts),
                   "lost_write_errors": dict(lost.first_error)}
        print(f"leonav nav: warning: nav.json not written ({exc.strerror or exc}); {lost_text(lost.counts)}",
              file=sys.stderr, flush=True)
    return result


def _operator(opts: NavOptions):
    """The operator-ephemeris folder (--operator-ephemerides), checked now, or None."""
    if opts.operator_ephemerides is None:
        return None
    from leonav_runtime.nav.navigator import leo_streams
    from leonav_runtime.orbits.operator_folder import OperatorFolder

    if not leo_streams(opts.nav.mode):
        raise UserInputError(f"--operator-ephemerides: mode {opts.nav.mode} measures no Starlink satellite "
                             "(it needs a Starlink mode such as fix+leo-alpha+imu or leo-phase+imu)")
    return OperatorFolder(opts.operator_ephemerides)


def _corrections(opts: NavOptions):
    """The differential-corrections store and its reader (--corrections), or None."""
    if opts.corrections is None:
        return None
    from leonav_runtime.base.client import CorrectionsClient
    from leonav_runtime.inputs.corrections import DEFAULT_MAX_AGE_S, DifferentialCorrections

    store = DifferentialCorrections(opts.corrections_max_age_s or DEFAULT_MAX_AGE_S)
    return CorrectionsClient(*opts.corrections, store)


def lost_text(counts: dict[str, int]) -> str:
    """'records not written: trajectory.csv 12, session/imu.raw 40' (or '' when none)."""
    if not counts:
        return ""
    return "records not written: " + ", ".join(f"{name} {n}" for name, n in sorted(counts.items()))


def exit_code(signum: int | None, summary: dict, session_info: dict) -> int:
    if signum == signal.SIGINT:
        return EXIT_SIGINT
    if signum == signal.SIGTERM:
        return EXIT_SIGTERM
    if summary.get("devices_lost"):
        return EXIT_DEVICE_LOST
    if not summary.get("started"):
        return EXIT_NEVER_NAVIGATED
    return EXIT_OK


def _describe_source(opts: NavOptions) -> dict:
    if opts.session is not None:
        return {"kind": "playback (paced, pty devices)" if opts.realtime else "playback (as fast as possible)",
                "session": str(opts.session)}
    return {"kind": "live devices", "gnss": opts.gnss, "imu": opts.imu, "sdr_index": opts.sdr_index,
            "gnss_baud": opts.gnss_baud, "imu_baud": opts.imu_baud}
