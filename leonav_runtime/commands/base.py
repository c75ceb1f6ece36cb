"""`leonav base`: a receiver at a known position serving differential corrections over TCP."""
from __future__ import annotations

import argparse
import json
import math
import signal
import sys
import threading
import time
import warnings
from pathlib import Path

from leonav_runtime.common.errors import UserInputError

EPILOG = """protocol: docs/corrections.md (HDR, then COR lines per satellite and epoch, HB once a second;
every line ends *hh, an XOR checksum). exit status: 0 served to the end (or --seconds), 2 bad
arguments or input, 3 the port is taken, 130 interrupted, 143 stopped (SIGTERM)."""


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "base", help="differential corrections: a receiver at a known position serves per-satellite corrections",
        formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EPILOG,
        description=(
            "Run the beacon pipeline on a base receiver's session at its known position, compute per-satellite "
            "corrections (measured Doppler-rate minus the value predicted from the element set at the known "
            "position, smoothed per satellite) and serve them as a line stream over TCP (127.0.0.1:2101 by "
            "default) to rovers (`leonav nav --corrections HOST:PORT`, `leonav replay --corrections FILE`)."))
    src = p.add_argument_group("source")
    src.add_argument("--from", dest="session", metavar="SESSION", default=None,
                     help="the base receiver's session folder (`leonav record` / `leonav session synth`)")
    src.add_argument("--simulate", metavar="PAIR", default=None,
                     help="a simulated pair's folder (leonav_runtime.base.simulated.write_pair): PAIR/base at the "
                          "position in PAIR/pair.json")
    src.add_argument("--position", nargs=3, type=float, default=None, metavar=("LAT", "LON", "H"),
                     help="the base's known position: WGS84 latitude, longitude (deg), ellipsoidal height (m)")
    src.add_argument("--tle", action="append", default=[], metavar="FILE", help="Starlink element sets")
    c = p.add_argument_group("corrections")
    c.add_argument("--smooth", type=float, default=None, metavar="S",
                   help="per-satellite averaging window (s, default 10)")
    c.add_argument("--pace", choices=("realtime", "fast"), default="realtime",
                   help="realtime: each correction sent when the base's clock reaches its time (the session's UTC "
                        "mapped to now at the start); fast: all of them to every rover as it connects")
    o = p.add_argument_group("outputs")
    o.add_argument("--listen", default="127.0.0.1:2101", metavar="HOST:PORT",
                   help="address served (default 127.0.0.1:2101; port 0 takes a free one and prints it)")
    o.add_argument("--record", metavar="FILE", default=None, help="also write every line sent to FILE")
    o.add_argument("--seconds", type=float, default=None,
                   help="stop after this many seconds (default: realtime, 2 s after the last correction; fast, "
                        "run until stopped)")
    p.set_defaults(func=run)


def _position(args) -> tuple[Path, tuple[float, float, float]]:
    if (args.session is None) == (args.simulate is None):
        raise UserInputError("base: give one of --from SESSION (with --position) or --simulate PAIR")
    if args.simulate is not None:
        pair = Path(args.simulate)
        try:
            doc = json.loads((pair / "pair.json").read_text())
            pos = tuple(float(v) for v in doc["base_position_deg_m"])
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise UserInputError(f"--simulate {pair}: pair.json unreadable ({exc}): expected a folder written by "
                                 f"base.simulated.write_pair") from None
        folder = pair / "base"
        if args.position is not None:
            pos = tuple(args.position)
    else:
        folder = Path(args.session)
        if args.position is None:
            raise UserInputError("--from SESSION: --position LAT LON H is required (the base's known position)")
        pos = tuple(args.position)
    if not folder.is_dir():
        raise UserInputError(f"{folder}: not a session folder")
    lat, lon, h = pos
    if not (-90 <= lat <= 90 and -180 <= lon <= 360 and math.isfinite(h)):
        raise UserInputError(f"--position {lat} {lon} {h}: expected latitude -90..90, longitude -180..360 deg, "
                             f"a finite height in m")
    return folder, pos


def build_corrections(folder: Path, pos, tle_files=(), smooth_s: float | None = None):
    """(corrections in time order, epoch_unix, notes) of the base session `folder` at `pos` (deg, deg, m)."""
    from leonav_runtime.base.compute import DEFAULT_SMOOTH_S, corrections_of_table
    from leonav_runtime.core import navfuncs
    from leonav_runtime.orbits.elements import load_element_files
    from leonav_runtime.replay import ReplayOptions
    from leonav_runtime.replay.run import decode_inputs

    nav = navfuncs.NavFunctions()
    elements = load_element_files(tle_files) if tle_files else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        inputs = decode_inputs(folder, ReplayOptions(), elements, None, nav)
    table = inputs.satellites.get("doppler_rate")
    if table is None or not table.t.size:
        raise UserInputError(f"{folder}: no Doppler-rate measurements from the base's capture "
                             f"({inputs.beacons.get('reason_empty') or 'no beacon associated'})")
    origin = (math.radians(pos[0]), math.radians(pos[1]), float(pos[2]))
    epoch_unix = inputs.epoch_utc.timestamp()
    corr = corrections_of_table(table, epoch_unix, origin, inputs.f_c_hz, nav,
                                DEFAULT_SMOOTH_S if smooth_s is None else smooth_s)
    if not corr:
        raise UserInputError(f"{folder}: {table.t.size} Doppler-rate measurements, but none gave a correction")
    return corr, epoch_unix, list(inputs.notes)


def run(args: argparse.Namespace) -> int:
    from leonav_runtime.base.client import parse_address

    folder, pos = _position(args)
    try:
        host, port = parse_address(args.listen, "--listen")
    except ValueError as exc:
        raise UserInputError(str(exc)) from None
    if args.smooth is not None and not (math.isfinite(args.smooth) and args.smooth >= 0):
        raise UserInputError(f"--smooth {args.smooth}: expected a window >= 0 s")
    # SIGINT / SIGTERM: while the corrections are built (no server yet) they end the build at once;
    # from then on they set a flag the serving loop reads, since an exception raised at any bytecode
    # could leave the server's lock held (between its acquire and the with block) and the close would
    # wait forever. Installed before the "serving" line: a client that signals on reading it is heard.
    # One raise is not enough: a library's bare `except:` swallows it where it lands (pynmea2 turns a
    # field it fails to convert, or an exception in its converter, into the field's text), so after
    # the signal SIGALRM raises again every REARM_S until the build has unwound.
    stop: list[int] = []
    building = [True]
    in_main = threading.current_thread() is threading.main_thread()    # (handlers only go there)
    rearm = in_main and hasattr(signal, "setitimer")

    def on_signal(signum, _frame):
        stop.append(signum)
        if building[0]:
            if rearm:
                signal.setitimer(signal.ITIMER_REAL, REARM_S, REARM_S)
            raise _Signalled(signum)

    def on_alarm(_signum, _frame):
        if building[0] and stop:
            raise _Signalled(stop[0])

    def build():
        try:
            try:
                return build_corrections(folder, pos, tuple(args.tle), args.smooth)
            finally:
                building[0] = False
                if rearm:
                    signal.setitimer(signal.ITIMER_REAL, 0)
        except _Signalled:
            return None
        except Exception:
            if stop:        # failed on what a swallowed raise left behind: the signal is the news
                return None
            raise

    handlers = {signal.SIGINT: on_signal, signal.SIGTERM: on_signal, **({signal.SIGALRM: on_alarm} if rearm else {})}
    previous = {s: signal.signal(s, h) for s, h in handlers.items()} if in_main else {}
    code = 0
    try:
        print(f"leonav base: building the corrections of {folder} (seconds) ...", file=sys.stderr, flush=True)
        built = build()
        if not stop:
            corr, epoch_unix, _ = built
            code = _serve(args, corr, epoch_unix, f"{folder} at {pos[0]:.7f}, {pos[1]:.7f}, {pos[2]:.2f} m",
                          pos, host, port, stop)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if stop:
        print(f"leonav base: {'interrupted (SIGINT)' if stop[0] == signal.SIGINT else 'stopped (SIGTERM)'}",
              file=sys.stderr, flush=True)
        return 130 if stop[0] == signal.SIGINT else 143
    return code


REARM_S = 0.05    # s between the raises after a signal during the build


class _Signalled(BaseException):
    """SIGINT or SIGTERM while the corrections are built (not an Exception: `except Exception` lets
    it through; a bare `except:` does not, hence the re-raise in `run`)."""


def _serve(args: argparse.Namespace, corr: list, epoch_unix: float, source: str, pos: tuple, host: str,
           port: int, stop: list[int]) -> int:
    """Serve the corrections (UTC epoch `epoch_unix`, s) until the end or until `stop` holds a signal
    number (0), or 3 when the port is taken."""
    from leonav_runtime.base import protocol
    from leonav_runtime.base.server import CorrectionsServer

    header = protocol.header_line(*pos)
    lines = [protocol.correction_line(c) for c in corr]
    try:
        server = CorrectionsServer(host, port, header + ("".join(lines) if args.pace == "fast" else ""))
    except OSError as exc:
        print(f"leonav base: error: --listen {host}:{port}: {exc.strerror or exc} (another program holds it? "
              f"try port 0)", file=sys.stderr)
        return 3
    record = None
    try:    # from here on the server and the record file are closed whatever happens
        record = open(args.record, "w") if args.record else None
        sats = len({c.norad_id for c in corr})
        print(f"leonav base: {len(corr)} corrections of {sats} satellites from {source}; "
              f"serving tcp://{server.address[0]}:{server.address[1]} ({args.pace})", flush=True)
        if record:
            record.write(header + ("".join(lines) if args.pace == "fast" else ""))
        wall0 = time.monotonic()
        start_utc = epoch_unix if args.pace == "realtime" else corr[0].t_utc_s
        end_s = args.seconds if args.seconds is not None else (
            corr[-1].t_utc_s - start_utc + 2.0 if args.pace == "realtime" else math.inf)
        k, next_hb = (0 if args.pace == "realtime" else len(lines)), 0.0
        while not stop and (now := time.monotonic() - wall0) < end_s:
            out = []
            while k < len(lines) and corr[k].t_utc_s <= start_utc + now:
                out.append(lines[k])
                k += 1
            if now >= next_hb:
                out.append(protocol.heartbeat_line(start_utc + now))
                next_hb += 1.0
            if out:
                server.send("".join(out))
                if record:
                    record.write("".join(out))
                    record.flush()
            time.sleep(0.05)
    finally:
        server.close()
        if record:
            record.close()
    if not stop:
        print(f"leonav base: done; {k} corrections sent; {server.counts}", flush=True)
    return 0
