"""`leonav record`: record the GNSS receiver, the WitMotion IMU and the RTL-SDR into a
session folder (raw logs, decoded CSVs, SigMF IQ, session.json). See hardware/README.md.
"""
from __future__ import annotations

import argparse

from hardware.sdr.capture import DEFAULT_LNB_LO_HZ
from leonav_runtime.gen.constants import STARLINK_BEACON_HZ


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
        "Raw bytes are flushed as they arrive, so Ctrl-C or an unplugged device leaves a "
        "readable session. Decoded CSVs and session.json describe the run.",
    )
    parser.add_argument("outdir", help="session folder to create (or reuse)")
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


def _run(args: argparse.Namespace) -> int:
    from hardware.sdr.capture import SdrSettings
    from hardware.session import RecordSession
    from leonav_runtime.errors import UserInputError

    if args.seconds <= 0:
        raise UserInputError(f"--seconds {args.seconds}: expected a positive duration")
    settings = SdrSettings(rf_center_hz=args.rf_hz, lnb_lo_hz=args.lnb_lo_hz,
                           sample_rate_hz=args.sdr_rate, gain_db=args.sdr_gain, ppm=args.sdr_ppm)
    session = RecordSession(args.outdir, gnss=args.gnss, imu=args.imu, sdr_index=args.sdr,
                            gnss_baud=args.gnss_baud, imu_baud=args.imu_baud,
                            configure=args.configure, sdr_settings=settings)
    info = session.run(args.seconds)
    print(f"session {args.outdir}: {info['status']}")
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
    return 0 if info["status"] != "interrupted" else 130
