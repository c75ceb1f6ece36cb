"""`leonav nav`: live navigation from the devices (or a recorded session played back), with live outputs."""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from leonav_runtime.common import output
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.replay.options import parse_latency

EPILOG = """exit status:
  0    ended as asked (--seconds elapsed or the played-back session ended) and navigated; also when
       some output records could not be written (full disk, I/O error): navigation and NMEA/MAVLink
       went on, nav.json files_complete=false and lost_writes (per file) say what is missing, and
       the summary says so (no code of its own: a non-zero run is marked FAILED, which it did not)
  1    never navigated (no GNSS time tag, usable fix or IMU data); outputs still written
  2    bad arguments or input; OUT in use by another run (one writer per folder); --nmea-pty PATH not free
  3    a device disappeared during the run (the filter went on with the rest; nav.json says which)
  130  interrupted (SIGINT, Ctrl-C)      143  stopped (SIGTERM, e.g. systemctl stop)
SIGINT/SIGTERM flush and close every output (trajectory.csv, solutions.jsonl, session/, nav.json).
A full disk never stops the run: what cannot be written is counted; nav.json and session.json are
written at the end in room kept for them (if nav.json still does not fit, one stderr line says so)."""


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "nav", help="live navigation: GNSS + WitMotion IMU (+ RTL-SDR Starlink) through the filter, NMEA/MAVLink out",
        formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EPILOG,
        description=(
            "Read the devices (like `leonav record`, and record them into OUT/session/), build the filter's inputs "
            "causally as they arrive (online GNSS time map, online IMU sample timing, fixes as they complete, "
            "Doppler-rate from the streaming beacon pipeline) through the same road as `leonav replay`, step the "
            "generated C filter on every IMU sample, and send solutions as NMEA (TCP, 127.0.0.1:10110 by default, "
            "and/or a pty), MAVLink and JSON lines. Writes trajectory.csv (lat/lon/h, ECEF, ENU, sigmas) and "
            "nav.json. With --from SESSION a recorded session is played back: with --realtime through pty devices "
            "at its recorded pace (the live code path), else as fast as possible."))
    src = p.add_argument_group("source")
    src.add_argument("--gnss", metavar="PORT", help="GNSS serial port (e.g. /dev/ttyAMA0, /dev/leonav-gnss)")
    src.add_argument("--imu", metavar="PORT", help="WitMotion serial port (e.g. /dev/ttyUSB0)")
    src.add_argument("--sdr", metavar="INDEX", type=int, default=None, help="RTL-SDR device index (Starlink beacons)")
    src.add_argument("--from", dest="session", metavar="SESSION", default=None,
                     help="play back a session folder (`leonav record` / `leonav session synth`) instead of devices")
    src.add_argument("--realtime", action="store_true",
                     help="with --from: feed pty devices at the recorded pace (the live path), not as fast as possible")
    src.add_argument("--gnss-baud", type=int, default=38400, help="GNSS baud (default 38400)")
    src.add_argument("--imu-baud", type=int, default=9600, help="IMU baud (default 9600)")
    src.add_argument("--configure", action="store_true", help="send the 10 Hz configuration first (as `leonav record`)")
    src.add_argument("--rf-hz", type=float, default=None,
                     help="beacon RF carrier tuned to baseband 0 (Hz, default 11.325e9); also the Doppler-rate carrier")
    src.add_argument("--lnb-lo-hz", type=float, default=None, help="LNB local oscillator (Hz, default 9.75e9)")
    src.add_argument("--sdr-rate", type=float, default=None, help="SDR sample rate (S/s, default 2.4e6)")
    src.add_argument("--sdr-gain", default="auto", help="SDR gain in dB or 'auto'")
    src.add_argument("--sdr-ppm", type=int, default=0, help="SDR frequency correction (ppm)")
    src.add_argument("--seconds", type=float, default=None, help="stop after this many seconds (default: run on)")
    src.add_argument("--no-record", action="store_true",
                     help="fast playback only: do not copy the session (live runs always record)")
    f = p.add_argument_group("filter")
    f.add_argument("--mode", default=None, metavar="MODE",
                   help="observables fused with the IMU: GNSS fixes, Starlink Doppler-rate and tracked carrier phase, "
                        "e.g. fix+imu, leo-alpha+imu, fix+leo-alpha+imu, leo-phase+imu, fix+leo-phase+imu, "
                        "leo-phase+alpha+imu (default fix+leo-alpha+imu with an SDR or capture, else fix+imu)")
    f.add_argument("--origin", nargs=3, type=float, default=None, metavar=("LAT", "LON", "H"),
                   help="ENU origin, deg deg m (default: the first GNSS fix)")
    f.add_argument("--yaw-deg", type=float, default=None, help="initial heading, deg from East towards North")
    f.add_argument("--gnss-latency", default="0", metavar="S|estimate",
                   help="receiver output latency, s, or 'estimate' (a filter state, prior 0 +- 0.3 s)")
    f.add_argument("--lag", type=float, default=3.5, metavar="S",
                   help="how late a measurement may arrive and still be put in its place (default 3.5 s: a Doppler-rate epoch comes up to ~2.7 s after its time)")
    f.add_argument("--tle", action="append", default=[], metavar="FILE", help="Starlink element sets (beacons)")
    f.add_argument("--operator-ephemerides", default=None, metavar="DIR",
                   help="folder of Starlink operator ephemerides (MANIFEST.txt and MEME_*.txt): a measured "
                        "satellite with a file takes its states from it and the file's covariance enters the "
                        "Doppler-rate's R (consider term); the others keep their element sets (docs/ephemerides.md)")
    f.add_argument("--corrections", metavar="HOST:PORT", default=None,
                   help="a base's differential corrections (`leonav base`), applied to the Doppler-rate; "
                        "reconnects when the base goes away (docs/corrections.md)")
    f.add_argument("--corrections-max-age", type=float, default=None, metavar="S",
                   help="oldest correction used (s, default 10); older: the measurement goes uncorrected")
    o = p.add_argument_group("outputs")
    o.add_argument("--nmea-port", default="10110", metavar="PORT|auto",
                   help="NMEA TCP server port (default 10110; auto: a free port, printed at the start and in "
                        "nav.json nmea_tcp; 0: no server)")
    o.add_argument("--nmea-max-clients", type=int, default=32, metavar="N",
                   help="most NMEA TCP clients at once (default 32); more are closed at once and counted")
    o.add_argument("--nmea-host", default="127.0.0.1", help="address the NMEA server listens on (default 127.0.0.1)")
    o.add_argument("--nmea-pty", metavar="PATH", default=None,
                   help="also write NMEA to a pty linked at PATH (a free path, or the pty link an earlier run "
                        "left: nothing else there is replaced)")
    o.add_argument("--mavlink", metavar="URL", default=None, help="MAVLink GPS_INPUT, e.g. udpout:127.0.0.1:14550")
    o.add_argument("--rate", type=float, default=10.0, help="live solutions per second (default 10)")
    o.add_argument("--trajectory-rate", type=float, default=10.0, help="trajectory.csv rows per second (default 10)")
    o.add_argument("--no-json", action="store_true", help="no solutions.jsonl")
    o.add_argument("--quiet", action="store_true", help="no status line")
    output.add_out_argument(o)
    p.set_defaults(func=run)


def _sdr_settings(args: argparse.Namespace):
    from leonav.hardware.sdr.capture import SdrSettings

    base = SdrSettings()
    gain = args.sdr_gain
    if gain != "auto":
        try:
            gain = float(gain)
        except ValueError:
            raise UserInputError(f"--sdr-gain {args.sdr_gain!r}: expected a number in dB or 'auto'") from None
    return SdrSettings(rf_center_hz=args.rf_hz or base.rf_center_hz, lnb_lo_hz=args.lnb_lo_hz or base.lnb_lo_hz,
                       sample_rate_hz=args.sdr_rate or base.sample_rate_hz, gain_db=gain, ppm=args.sdr_ppm)


def _nmea_port(text: str) -> int | str:
    """--nmea-port: 0..65535 or 'auto'."""
    if str(text).strip().lower() == "auto":
        return "auto"
    try:
        port = int(text)
    except ValueError:
        port = -1
    if not 0 <= port <= 65535:
        raise UserInputError(f"--nmea-port {text}: expected a port 1..65535, auto (a free port) or 0 (off)")
    return port


def _corrections_address(args: argparse.Namespace) -> tuple[str, int] | None:
    from leonav_runtime.base.client import parse_address

    if args.corrections is None:
        if args.corrections_max_age is not None:
            raise UserInputError("--corrections-max-age: only with --corrections HOST:PORT")
        return None
    try:
        return parse_address(args.corrections)
    except ValueError as exc:
        raise UserInputError(str(exc)) from None


def _max_age(args: argparse.Namespace) -> float | None:
    v = args.corrections_max_age
    if v is not None and not (math.isfinite(v) and v > 0):
        raise UserInputError(f"--corrections-max-age {v}: expected a positive number of seconds")
    return v


def options_from_args(args: argparse.Namespace):
    from leonav_runtime.nav.navigator import NavConfig, nav_mode
    from leonav_runtime.nav.road import RoadConfig
    from leonav_runtime.nav.run import NavOptions

    if args.session is not None and (args.gnss or args.imu or args.sdr is not None):
        raise UserInputError("nav: --from SESSION plays back a session; do not give --gnss/--imu/--sdr with it")
    if args.session is not None and not Path(args.session).is_dir():
        raise UserInputError(f"--from {args.session}: not a session folder")
    if args.realtime and args.session is None:
        raise UserInputError("--realtime: only with --from SESSION")
    for name in ("rate", "trajectory_rate", "lag"):
        v = getattr(args, name)
        if not (math.isfinite(v) and v > 0):
            raise UserInputError(f"--{name.replace('_', '-')}: {v!r}: expected a positive number")
    if args.seconds is not None and not (math.isfinite(args.seconds) and args.seconds > 0):
        raise UserInputError(f"--seconds: {args.seconds!r}: expected a positive duration")
    port = _nmea_port(args.nmea_port)
    if not 1 <= args.nmea_max_clients <= 1000:
        raise UserInputError(f"--nmea-max-clients: {args.nmea_max_clients}: expected 1..1000")
    has_sdr = args.sdr is not None or (args.session is not None and (Path(args.session) / "sdr.cu8").exists())
    mode = args.mode or ("fix+leo-alpha+imu" if has_sdr else "fix+imu")
    nav_mode(mode)
    road = RoadConfig(origin_deg=tuple(args.origin) if args.origin else None, yaw_deg=args.yaw_deg,
                      gnss_latency_s=parse_latency(str(args.gnss_latency)))
    cfg = NavConfig(mode=mode, road=road, lag_s=args.lag, output_rate_hz=args.rate,
                    trajectory_rate_hz=args.trajectory_rate)
    return NavOptions(
        out_dir=output.results_dir(args.out, "nav"), nav=cfg, session=Path(args.session) if args.session else None,
        realtime=args.realtime, gnss=args.gnss, imu=args.imu, sdr_index=args.sdr,
        gnss_baud=args.gnss_baud, imu_baud=args.imu_baud, configure=args.configure,
        sdr_settings=_sdr_settings(args) if args.sdr is not None else None, seconds=args.seconds,
        record=not args.no_record, tcp=None if port == 0 else (args.nmea_host, 0 if port == "auto" else port),
        nmea_max_clients=args.nmea_max_clients,
        pty_link=args.nmea_pty, mavlink=args.mavlink, json_lines=not args.no_json,
        status=False if args.quiet else None, tle_files=tuple(args.tle),
        corrections=_corrections_address(args), corrections_max_age_s=_max_age(args),
        operator_ephemerides=args.operator_ephemerides)


def run(args: argparse.Namespace) -> int:
    from leonav_runtime.nav.run import run_nav

    opts = options_from_args(args)
    res = run_nav(opts)
    lat = res.get("latency_ms") or {}
    print(f"leonav nav: {res['status']} ({res['end_reason']}), exit {res['exit_code']}: {res['exit_meaning']}")
    print(f"  {res.get('trajectory_rows', 0)} trajectory rows -> {opts.out_dir}/trajectory.csv; "
          f"{res['outputs'].get('solutions', 0)} live solutions"
          + (f"; latency p50 {lat['p50']:.2f} ms, p99 {lat['p99']:.2f} ms" if lat else ""))
    if res.get("lost_writes"):
        from leonav_runtime.nav.run import lost_text

        first = next(iter(res["lost_write_errors"].values()), "")
        print(f"  OUTPUT FILES INCOMPLETE: {lost_text(res['lost_writes'])} (first: {first})")
    for name, reason in (res.get("devices_lost") or {}).items():
        print(f"  {name} lost: {reason}")
    junk = {k: v.get("junk_bytes", 0) for k, v in (res.get("rejected") or {}).items() if v.get("junk_bytes")}
    if junk:
        print(f"  garbage bytes skipped: {junk}")
    sys.stdout.flush()
    return int(res["exit_code"])
