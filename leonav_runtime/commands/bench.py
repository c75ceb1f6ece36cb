"""`leonav bench`: speed of the generated filter, C loop vs CasADi vs NumPy vs bare C.

The implementation is `benchmarks/bench_filter.py` of the source checkout (it also needs
`benchmarks/numpy_ekf.py`, `benchmarks/bench_bare_loop.c` and `benchmarks/bench_sweep.py`, which
are not installed with the package); this command runs it and writes `bench.json` into the
results folder.
"""
from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path
from types import ModuleType

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.common.output import add_out_argument

BENCH_SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_filter.py"


def _bench_module() -> ModuleType:
    if not BENCH_SCRIPT.exists():
        raise UserInputError(
            f"{BENCH_SCRIPT}: not found; `leonav bench` runs from a source checkout of leonav "
            "(benchmarks/ is not part of the installed package)"
        )
    spec = importlib.util.spec_from_file_location("leonav_bench_filter", BENCH_SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


def _run(args: argparse.Namespace) -> int:
    if args.seconds <= 0 or args.repeats < 1 or args.py_repeats < 1 or args.sweep_trials < 0:
        raise UserInputError("--seconds must be > 0, --repeats/--py-repeats >= 1 and --sweep-trials >= 0")
    _bench_module().run_benchmark(args.seconds, args.repeats, args.py_repeats, args.out, args.sweep_trials)
    return 0


def register(subparsers) -> None:
    """Add the `bench` subcommand."""
    parser = subparsers.add_parser(
        "bench",
        help="time the filter: C loop vs CasADi from Python vs NumPy vs bare generated C",
        description="Time per IMU step of the generated filter (100 Hz IMU, 10 Hz GPS with 8 "
        "pseudoranges, 1 Hz Starlink with 10 Doppler-rates): (a) C loop, (b) the same CasADi "
        "Functions called from Python, (c) plain NumPy, (d) bare generated C loop; plus code "
        "size and compile time; then the paper sweep's CPU against its C floor (trials x IMU "
        "steps x the C loop's CPU per step, measured in the same run). Writes bench.json.",
    )
    parser.add_argument("--seconds", type=float, default=20.0, help="stream length, s (default 20)")
    parser.add_argument("--repeats", type=int, default=20, help="repeats of the C paths, best taken (default 20)")
    parser.add_argument("--py-repeats", type=int, default=2, help="repeats of the Python paths (default 2)")
    parser.add_argument("--sweep-trials", type=int, default=100, metavar="N",
                        help="trials per point of the paper sweep timed against its C floor (default 100, "
                             "the paper's; 0 skips it)")
    add_out_argument(parser)
    parser.set_defaults(func=_run)
