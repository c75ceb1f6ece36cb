"""`leonav export-records SESSION`: a session's filter inputs as the files of the standalone Pi program.

`hardware/pi/leonav_filter RECORDS.bin INIT.bin OUT.csv [GATE_NIS]` (hardware/pi/leonav_filter.c)
reads a raw array of `leonav_record` (the NumPy twin `records.RECORD_DTYPE`, little-endian,
aligned as the C struct on x86-64 and aarch64) and an init file of little-endian doubles
x0 (NX), P0 (NDX*NDX, column-major), p (NP). This command builds them exactly as `leonav replay`
does for one mode (`replay.decode_inputs` -> `FilterInputs.merged`), so the program's run equals
the replay's filter run.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from leonav_runtime.common import output
from leonav_runtime.common.errors import UserInputError


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "export-records",
        help="write a session's filter inputs (records.bin, init.bin) for hardware/pi/leonav_filter",
        description=("Decode a session as `leonav replay` does and write, for one mode, records.bin (raw "
                     "leonav_record array), init.bin (x0, P0 column-major, p as little-endian doubles) and "
                     "export.json (sizes, counts, epoch, origin, the command to run). Run them with "
                     "`make -C hardware/pi && hardware/pi/build/leonav_filter records.bin init.bin out.csv`."))
    p.add_argument("session", metavar="SESSION", help="session folder (`leonav record`, `leonav nav`, `leonav session synth`)")
    p.add_argument("--mode", default="fix+imu", help="fix+imu, leo-alpha+imu, fix+leo-alpha+imu, pseudorange+imu or "
                                                      "pseudorange+leo-alpha+imu (default fix+imu)")
    p.add_argument("--nav", action="append", default=[], metavar="RINEX_NAV",
                   help="RINEX navigation file(s) for the pseudorange modes (besides the session's RXM-SFRBX)")
    p.add_argument("--tle", action="append", default=[], metavar="FILE", help="Starlink element sets (LEO modes)")
    p.add_argument("--origin", nargs=3, type=float, default=None, metavar=("LAT", "LON", "H"),
                   help="ENU origin, deg deg m (default: the first GNSS fix)")
    p.add_argument("--yaw-deg", type=float, default=None, help="initial heading, deg from East towards North")
    p.add_argument("--gnss-latency", type=float, default=0.0, metavar="S", help="receiver output latency, s")
    output.add_out_argument(p)
    p.set_defaults(func=run)


def export(session: Path, out: Path, options, elements=None) -> dict:
    """records.bin, init.bin, export.json for the first mode of `options`; returns export.json's content."""
    from leonav_runtime.core import navfuncs, records
    from leonav_runtime.gen import state_layout as L
    from leonav_runtime.gen.constants import CHI2_1DOF_999
    from leonav_runtime.replay import decode_inputs, replay_mode

    nav = navfuncs.NavFunctions()
    inputs = decode_inputs(Path(session), options, elements, out, nav)
    mode = options.modes[0]
    if mode in inputs.skipped:
        raise UserInputError(f"{session}: mode {mode} cannot run: {inputs.skipped[mode]}")
    recs = np.ascontiguousarray(inputs.merged(replay_mode(mode).streams))
    recs.tofile(out / "records.bin")
    init = np.concatenate([inputs.x0, np.asarray(inputs.P0).ravel(order="F"), inputs.params]).astype("<f8")
    init.tofile(out / "init.bin")
    kinds, counts = np.unique(recs["kind"], return_counts=True)
    names = {v: k for k, v in nav.library.meas_ids.items()} | {records.KIND_IMU: "imu"}
    info = {
        "session": str(session), "mode": mode, "records": int(recs.size),
        "records_per_kind": {names.get(int(k), str(int(k))): int(n) for k, n in zip(kinds, counts)},
        "record_bytes": int(recs.dtype.itemsize), "init_doubles": int(init.size),
        "NX": int(L.NX), "NDX": int(L.NDX), "NP": int(L.NP), "gate_nis_default": CHI2_1DOF_999,
        "epoch_utc": inputs.epoch_utc, "origin_deg": [math.degrees(inputs.origin[0]), math.degrees(inputs.origin[1]),
                                                      inputs.origin[2]],
        "t_start_s": inputs.init.get("start_s"), "notes": inputs.notes,
        "run": f"hardware/pi/build/leonav_filter {out / 'records.bin'} {out / 'init.bin'} {out / 'out.csv'}",
    }
    output.write_json(out / "export.json", info)
    return info


def run(args: argparse.Namespace) -> int:
    from leonav_runtime.orbits.elements import load_element_files
    from leonav_runtime.replay import ReplayOptions, check_options

    if not Path(args.session).is_dir():
        raise UserInputError(f"{args.session}: not a session folder")
    if not (math.isfinite(args.gnss_latency) and 0 <= args.gnss_latency < 1):
        raise UserInputError(f"--gnss-latency: {args.gnss_latency!r}: expected seconds in [0, 1)")
    options = check_options(ReplayOptions(modes=(args.mode,), origin_deg=tuple(args.origin) if args.origin else None,
                                          yaw_deg=args.yaw_deg, gnss_latency_s=args.gnss_latency,
                                          nav_paths=tuple(args.nav)))
    out = output.results_dir(args.out, "export-records")
    info = export(Path(args.session), out, options, load_element_files(args.tle))
    print(f"export-records {args.session} ({info['mode']}) -> {out}: {info['records']} records "
          f"({', '.join(f'{k} {n}' for k, n in info['records_per_kind'].items())}), "
          f"{info['record_bytes']} bytes each; init.bin {info['init_doubles']} doubles")
    print(f"  run: make -C hardware/pi && {info['run']}")
    return 0
