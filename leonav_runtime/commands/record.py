"""`leonav record`: record the GNSS receiver, the WitMotion IMU and the RTL-SDR into a
session folder (raw logs, decoded CSVs, SigMF IQ, session.json). See hardware/README.md.
"""
from __future__ import annotations

import argparse
import math
import shutil
from pathlib import Path

from leonav.hardware.sdr.capture import DEFAULT_LNB_LO_HZ
from leonav_runtime.gen.constants import STARLINK_BEACON_HZ

MAX_SECONDS = 30 * 86400             # one recording at most 30 days
BAUD_RANGE = (50, 12_000_000)        # serial rates a UART / USB adapter can run (FTDI tops at 12 Mbaud)
SDR_RATE_RANGE = (225e3, 3.2e6)      # RTL-SDR sample rates (S/s)
SDR_GAIN_RANGE_DB = (0.0, 60.0)
SDR_BYTES_PER_SAMPLE = 2             # cu8: one byte I, one byte Q
DISK_MARGIN_BYTES = 100e6            # left free beside the capture


def _gain(text: str) -> float | str:
    if text == "auto":
        return "auto"
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--sdr-gain {text!r}: expected a number in dB or 'auto'")


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "record",
        help="record GNSS (NMEA/UBX) + WitMotion IMU + RTL-SDR IQ into a session folder",
        description="Record serial GNSS and IMU streams and an RTL-SDR capture of the LNB IF. "
        "Raw bytes are flushed as they arrive, so Ctrl-C, SIGTERM, SIGHUP or an unplugged device leaves a "
        "readable session (exit status 130 for a signal). Decoded CSVs and session.json describe the run; "
        "status \"failed\" (exit 3 or 1) when a device thread ended on an error such as a full disk. Limits: "
        "--seconds up to 30 days, baud 50..12000000, with --sdr the capture must fit on the disk.",
    )
    parser.add_argument("outdir", help="session folder to create (or an empty one; a recording is never "
                        "overwritten)")
    parser.add_argument("--gnss", metavar="PORT", help="GNSS serial port or pyserial URL (e.g. /dev/ttyAMA0)")
    parser.add_argument("--gnss-baud", type=int, default=38400, help="GNSS baud rate (default 38400, the M10 default)")
    parser.add_argument("--imu", metavar="PORT", help="WitMotion serial port (e.g. /dev/ttyUSB0)")
    parser.add_argument("--imu-baud", type=int, default=9600, help="IMU baud rate (default 9600, WT901C-TTL default)")
    parser.add_argument("--sdr", metavar="INDEX", type=int, default=None, help="RTL-SDR device index")
    parser.add_argument("--seconds", type=float, required=True, help="recording duration (s)")
    parser.add_argument("--configure", action="store_true",
                        help="send the 10 Hz configuration first (UBX CFG-VALSET: 100 ms rate, NAV-PVT, "
                        "RXM-RAWX/MEASX on UART1; WitMotion: unlock, 10 Hz, save)")
    parser.add_argument("--rf-hz", type=float, default=STARLINK_BEACON_HZ,
                        help="beacon RF carrier, tuned to baseband 0 (Hz, default %(default)g); `leonav replay` "
                        "takes the Doppler-rate carrier from it")
    parser.add_argument("--lnb-lo-hz", type=float, default=DEFAULT_LNB_LO_HZ,
                        help="LNB local oscillator (Hz, default %(default)g)")
    parser.add_argument("--sdr-rate", type=float, default=2.4e6, help="SDR sample rate (S/s, default 2.4e6)")
    parser.add_argument("--sdr-gain", type=_gain, default="auto", help="SDR gain in dB or 'auto'")
    parser.add_argument("--sdr-ppm", type=int, default=0, help="SDR frequency correction (ppm)")
    parser.set_defaults(func=_run)


def _existing_parent(path: Path) -> Path:
    path = path.absolute()
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def check_options(args: argparse.Namespace) -> None:
    """Every option in range before a device is opened or a file written (UserInputError)."""
    from leonav_runtime.common.errors import UserInputError

    if not (math.isfinite(args.seconds) and 0 < args.seconds <= MAX_SECONDS):
        raise UserInputError(f"--seconds {args.seconds!r}: expected a duration in (0, {MAX_SECONDS}] s (30 days)")
    for option, baud in (("--gnss-baud", args.gnss_baud), ("--imu-baud", args.imu_baud)):
        if not BAUD_RANGE[0] <= baud <= BAUD_RANGE[1]:
            raise UserInputError(f"{option} {baud}: expected a baud rate in {BAUD_RANGE[0]}..{BAUD_RANGE[1]}")
    for option, hz in (("--rf-hz", args.rf_hz), ("--lnb-lo-hz", args.lnb_lo_hz)):
        if not (math.isfinite(hz) and hz > 0):
            raise UserInputError(f"{option} {hz!r}: expected a positive frequency in Hz")
    if not (math.isfinite(args.sdr_rate) and SDR_RATE_RANGE[0] <= args.sdr_rate <= SDR_RATE_RANGE[1]):
        raise UserInputError(f"--sdr-rate {args.sdr_rate!r}: expected {SDR_RATE_RANGE[0]:g}..{SDR_RATE_RANGE[1]:g} "
                             "samples/s (RTL-SDR)")
    if args.sdr_gain != "auto" and not (math.isfinite(args.sdr_gain)
                                        and SDR_GAIN_RANGE_DB[0] <= args.sdr_gain <= SDR_GAIN_RANGE_DB[1]):
        raise UserInputError(f"--sdr-gain {args.sdr_gain!r}: expected 'auto' or {SDR_GAIN_RANGE_DB[0]:g}.."
                             f"{SDR_GAIN_RANGE_DB[1]:g} dB")
    if abs(args.sdr_ppm) > 1000:
        raise UserInputError(f"--sdr-ppm {args.sdr_ppm}: expected -1000..1000")
    if args.sdr is not None:
        where = _existing_parent(Path(args.outdir))
        need = args.seconds * args.sdr_rate * SDR_BYTES_PER_SAMPLE + DISK_MARGIN_BYTES
        free = shutil.disk_usage(where).free
        if need > free:
            raise UserInputError(
                f"--seconds {args.seconds:g} at --sdr-rate {args.sdr_rate:g} S/s needs {need / 1e9:.1f} GB for "
                f"sdr.cu8 but {free / 1e9:.1f} GB are free on {where}; record less (--seconds) or at a lower "
                "--sdr-rate, or free the disk")


def _run(args: argparse.Namespace) -> int:
    from leonav.hardware.sdr.capture import SdrSettings
    from leonav.hardware.session import RecordSession

    check_options(args)
    from leonav_runtime.common import output

    # created here so that a recording that fails before any byte leaves no empty folder behind
    output.results_dir(args.outdir, "record")
    settings = SdrSettings(rf_center_hz=args.rf_hz, lnb_lo_hz=args.lnb_lo_hz,
                           sample_rate_hz=args.sdr_rate, gain_db=args.sdr_gain, ppm=args.sdr_ppm)
    session = RecordSession(args.outdir, gnss=args.gnss, imu=args.imu, sdr_index=args.sdr,
                            gnss_baud=args.gnss_baud, imu_baud=args.imu_baud,
                            configure=args.configure, sdr_settings=settings)
    with session.stop_signals():   # a second Ctrl-C while the summary is printed is ignored too
        info = session.run(args.seconds)
        _print_summary(args, info)
    if info["status"] == "failed":   # one line from the CLI, with the exit status of that error
        failure = next((run.exception for run in session.devices if run.exception is not None), None)
        raise failure or RuntimeError("a device thread failed (see session.json)")
    return 0 if info["status"] != "interrupted" else 130


def _print_summary(args: argparse.Namespace, info: dict) -> None:
    status = info["status"] + (f" ({info['stop_signal']})" if info.get("stop_signal") else "")
    print(f"session {args.outdir}: {status}")
    for dev in info["devices"]:
        accepted = dev.get("accepted", {})
        rejected = dev.get("rejected", {})
        detail = dev.get("error") or dev.get("end_reason", "")
        if dev["kind"] == "sdr":
            print(f"  sdr {dev['port']}: {dev.get('n_samples', 0)} samples ({detail})")
        else:
            print(f"  {dev['kind']} {dev['port']}: {dev.get('bytes_read', 0)} bytes, "
                  f"accepted {accepted}, rejected {rejected} ({detail})")
    tm = info.get("time_map", {})
    if tm.get("n_tags"):
        print(f"  time map from {tm['source']}: {tm['n_tags']} tags, "
              f"residual std {tm['residual_std_s'] * 1e3:.1f} ms")
    else:
        print("  time map: no GNSS time tags (imu.csv has no UTC column values)")
