"""Operator ephemerides vs element sets: CPU cost of satellite ECEF states on the same grid.

    python benchmarks/bench_operator_ephemeris.py [--sats 45] [--duration 300] [--rate 10] [--repeats 5]

The same satellites (the generated Starlink Walker set at the epoch) as element sets and as
operator ephemeris files (their SGP4 orbits written in the operator's format every 60 s over
2 h, read back; not timed). Timed side by side, interleaved so the machine's load hits them
alike, with the thread's CPU clock (time.thread_time; wall time beside it):

  sgp4            `propagate_ecef` r, v, a (the element-set path)
  operator        `operator_states_ecef` r, v, a and the 6 x 6 ECEF covariance
  operator, 1 s   the same at 1 Hz (the rotation matrices dominate less)

and the CPU of reading and writing one 72 h file (the operator's length) after them.

Prints the median of --repeats per variant, satellite-epochs per CPU second and the ratio to
SGP4, and the load average at the start and the end (the machine is shared).
"""
from __future__ import annotations

import argparse
import datetime as dt
import os
import statistics
import tempfile
import time
import warnings

import numpy as np

from leonav_runtime.orbits import (
    parse_elements_text,
    propagate_ecef,
    starlink_walker_tle,
)
from leonav_runtime.orbits.operator_ephemeris import load_folder, parse_text, write_file, write_text
from leonav_runtime.orbits.operator_states import (
    ephemerides_from_elements,
    operator_states_ecef,
)


def _files(elements, epoch: dt.datetime, folder: str) -> None:
    made = ephemerides_from_elements(elements, epoch, np.arange(-600.0, 7200.0 + 1.0, 60.0),
                                     np.diag([0.5, 1.0, 1.2, 2e-6, 1e-6, 5e-6]))
    for j, eph in enumerate(made.ephemerides.values()):
        write_file(eph, folder, serial=j)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sats", type=int, default=45)
    parser.add_argument("--duration", type=float, default=300.0, help="s")
    parser.add_argument("--rate", type=float, default=10.0, help="Hz")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    load0 = os.getloadavg()
    epoch = dt.datetime(2026, 2, 23, 12, 0, 0, tzinfo=dt.timezone.utc)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        walker = parse_elements_text(starlink_walker_tle(epoch), "walker")
    elements = walker.select(np.arange(args.sats) * (len(walker) // args.sats))
    names = list(elements.names)
    t_fast = np.arange(0.0, args.duration, 1.0 / args.rate)
    t_slow = np.arange(0.0, args.duration, 1.0)
    with tempfile.TemporaryDirectory() as folder, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        _files(elements, epoch, folder)
        ephs = load_folder(folder)
        variants = {
            f"sgp4 propagate_ecef ({args.rate:g} Hz)": (lambda: propagate_ecef(elements, epoch, t_fast), t_fast.size),
            f"operator states + covariance ({args.rate:g} Hz)": (lambda: operator_states_ecef(ephs, names, epoch, t_fast),
                                                                 t_fast.size),
            "operator states + covariance (1 Hz)": (lambda: operator_states_ecef(ephs, names, epoch, t_slow), t_slow.size),
        }
        cpu: dict[str, list[float]] = {k: [] for k in variants}
        wall: dict[str, list[float]] = {k: [] for k in variants}
        for fn, _ in variants.values():      # warm-up (EOP table, imports)
            fn()
        for _ in range(args.repeats):
            for name, (fn, _) in variants.items():
                c0, w0 = time.thread_time(), time.perf_counter()
                fn()
                cpu[name].append(time.thread_time() - c0)
                wall[name].append(time.perf_counter() - w0)
        # reading: one 72 h file (4321 records) parsed, and written
        day3 = ephemerides_from_elements(elements.select([0]), epoch, np.arange(0.0, 72 * 3600.0 + 1.0, 60.0),
                                         np.eye(6))
        text = write_text(next(iter(day3.ephemerides.values())))
        parse_cpu, write_cpu = [], []
        for _ in range(args.repeats):
            c0 = time.thread_time()
            eph = parse_text(text, "bench")
            c1 = time.thread_time()
            write_text(eph)
            parse_cpu.append(c1 - c0)
            write_cpu.append(time.thread_time() - c1)
    load1 = os.getloadavg()
    ref = statistics.median(next(iter(cpu.values())))
    print(f"{args.sats} satellites, {args.duration:g} s; median of {args.repeats}; "
          f"load average {load0[0]:.1f} at start, {load1[0]:.1f} at end ({os.cpu_count()} cores)")
    print(f"{'variant':48s} {'CPU ms':>9s} {'wall ms':>9s} {'sat-epochs/CPU s':>17s} {'CPU / sgp4':>10s}")
    for name, (_, nt) in variants.items():
        c = statistics.median(cpu[name])
        print(f"{name:48s} {1e3 * c:9.1f} {1e3 * statistics.median(wall[name]):9.1f} "
              f"{args.sats * nt / c:17.3g} {c / ref:10.2f}")
    print(f"one 72 h file ({len(text) / 1e6:.1f} MB, 4321 records): parse {1e3 * statistics.median(parse_cpu):.0f} ms "
          f"CPU, write {1e3 * statistics.median(write_cpu):.0f} ms CPU")


if __name__ == "__main__":
    main()
