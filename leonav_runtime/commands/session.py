"""`leonav session synth OUTDIR`: a synthetic session in `leonav record`'s exact formats, with truth."""
from __future__ import annotations

import argparse
import math
from pathlib import Path

from leonav_runtime.common import output
from leonav_runtime.common.errors import UserInputError


def register(subparsers) -> None:
    p = subparsers.add_parser("session", help="session tools: `session synth` writes a synthetic recorded session")
    sub = p.add_subparsers(dest="session_command", metavar="ACTION")
    s = sub.add_parser(
        "synth",
        help="write a synthetic session (NMEA, WitMotion, RTL-SDR IQ, chunk stamps, session.json) plus truth.csv",
        description=(
            "Simulate the paper's rig at a static site (default: Rochester NY, 2026-02-23T12:00Z, facing North): "
            "u-blox NMEA GGA/RMC/GST at 10 Hz, WitMotion 0x51/0x52/0x53 at 10 Hz (WT901 noise and biases, int16 "
            "quantization), a Starlink beacon capture with N tones, serial timing and host read stamps, and write "
            "them as `leonav record` does, plus truth.csv and synthetic.json. With --compare, also replay it and "
            "run the same inputs directly through the filter (no bytes) and print both RMSEs."),
    )
    s.add_argument("outdir", metavar="OUTDIR", help="session folder to create (must be new or empty)")
    s.add_argument("--seconds", type=float, default=20.0, help="session length, s (default 20)")
    s.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    s.add_argument("--epoch", default=None, metavar="ISO-UTC", help="UTC of t = 0 (default 2026-02-23T12:00:00Z)")
    s.add_argument("--sdr-rate", type=float, default=400e3, metavar="HZ",
                   help="IQ sample rate, Hz (default 400e3 to keep files small; the recorder's default is 2.4e6)")
    s.add_argument("--n-sats", type=int, default=5, metavar="N", help="Starlink tones in the capture (default 5)")
    s.add_argument("--cn0", type=float, default=40.0, metavar="DBHZ", help="tone C/N0, dB-Hz (default 40)")
    s.add_argument("--tle", action="append", default=[], metavar="FILE",
                   help="Starlink element sets for the tones (default: built-in Walker constellation)")
    s.add_argument("--no-sdr", action="store_true", help="no sdr.cu8 (GNSS and IMU only)")
    s.add_argument("--overwrite", action="store_true", help="replace a non-empty OUTDIR")
    s.add_argument("--compare", action="store_true",
                   help="replay the session and run it directly through the filter; results in --out")
    output.add_out_argument(s)
    s.set_defaults(func=run_synth)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def run_synth(args: argparse.Namespace) -> int:
    from leonav_runtime.common.progress import progress as make_progress

    from leonav_runtime import replay
    from leonav_runtime.simulation import session_synth as ss
    from leonav_runtime.beacons.capture_io import parse_utc
    from leonav_runtime.orbits import load_element_files

    if not (math.isfinite(args.seconds) and 2.0 <= args.seconds <= 3600):
        raise UserInputError(f"--seconds: {args.seconds!r}: expected 2 to 3600 s")
    if not (math.isfinite(args.sdr_rate) and 200e3 <= args.sdr_rate <= 3.2e6):
        raise UserInputError(f"--sdr-rate: {args.sdr_rate!r}: expected 2e5 to 3.2e6 Hz")
    if args.n_sats < 1:
        raise UserInputError(f"--n-sats: {args.n_sats}: expected at least 1")
    cfg = ss.SynthSessionConfig(seconds=args.seconds, seed=args.seed, sdr=not args.no_sdr, sdr_rate_hz=args.sdr_rate,
                                n_satellites=args.n_sats, cn0_dbhz=args.cn0)
    if args.epoch:
        cfg.epoch_utc = parse_utc(args.epoch, "--epoch", require_zone=True)
    elements = load_element_files(args.tle)
    total = int((cfg.seconds - cfg.sdr_start_s - 0.05) * cfg.sdr_rate_hz) if cfg.sdr else 0
    with make_progress(total, "synthesizing IQ", "S", unit_scale=True, leave=False) as bar:
        synth = ss.write_synthetic_session(args.outdir, cfg, elements, overwrite=args.overwrite, progress=bar.update)
    files = sorted(p.name for p in Path(args.outdir).iterdir())
    print(f"synthetic session {args.outdir}: {len(synth.fix_t)} GNSS epochs, {synth.u_meas.shape[0]} IMU samples"
          + (f", {len(synth.sdr_info.get('norad_ids', []))} Starlink tones ({', '.join(synth.sdr_info['names'])})"
             if synth.sdr_info else ""))
    print(f"  files: {', '.join(files)}")
    if args.compare:
        out = output.results_dir(args.out, "session-synth")
        res = replay.compare_replay_direct(synth, out, elements=elements)
        print(f"  replay vs direct simulation (same truth and noise, no bytes) -> {out}")
        print(f"  {'mode':<20} {'pos RMSE m':>17} {'vel m/s':>15} {'att deg':>15}")
        print(f"  {'':<20} {'replay / direct':>17} {'replay / direct':>15} {'replay / direct':>15}")
        for mode, row in res["table"].items():
            cells = [f"{row[k]['replay']:.3f} / {row[k]['direct']:.3f}" for k in
                     ("rmse_position_m", "rmse_velocity_mps", "rmse_attitude_deg")]
            print(f"  {mode:<20} {cells[0]:>17} {cells[1]:>15} {cells[2]:>15}")
    return 0
