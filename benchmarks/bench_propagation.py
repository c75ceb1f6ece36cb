"""Propagation throughput: `propagate_ecef` vs a bare `SatrecArray.sgp4` on the same grid.

    .venv/bin/python benchmarks/bench_propagation.py [--sats 10000] [--epochs 60] [--repeats 7] [--tle FILE]

Runs the three variants interleaved (so machine load hits them alike), prints the median
time of each, satellite-epochs per second and the ratio to the bare SGP4 call. Goal: the
whole wrapper (TEME->ECEF + acceleration + failure bookkeeping) at most 1.5x bare SGP4.
Elements: the generated Starlink Walker set (or --tle FILE), repeated to --sats.
"""
from __future__ import annotations

import argparse
import datetime as dt
import logging
import statistics
import time
import warnings

import numpy as np

from leonav_runtime.orbits import load_elements, propagate_ecef, starlink_walker_tle
from leonav_runtime.orbits import parse_elements_text
from leonav_runtime.orbits.elements import julian_date_split


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sats", type=int, default=10_000)
    parser.add_argument("--epochs", type=int, default=60)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--tle", default=None, help="element file (default: generated Starlink Walker set)")
    args = parser.parse_args()
    logging.getLogger("leonav.orbits").setLevel(logging.ERROR)  # stale-element notes, once per call

    epoch = dt.datetime(2026, 2, 23, 12, 0, 0, tzinfo=dt.timezone.utc)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        base = load_elements(args.tle) if args.tle else parse_elements_text(starlink_walker_tle(epoch), "walker")
    elements = base.select(np.arange(args.sats) % len(base))
    t_s = np.arange(args.epochs, dtype=float) * 1.0
    jd_whole, jd_frac = julian_date_split(epoch)
    jd = np.full(t_s.shape, jd_whole)
    fr = jd_frac + t_s / 86400.0
    satrec_array = elements.satrec_array  # built once, shared by all variants

    def bare() -> None:
        satrec_array.sgp4(jd, fr)

    def ecef_rv() -> None:
        propagate_ecef(elements, epoch, t_s, acceleration=False)

    def ecef_rva() -> None:
        propagate_ecef(elements, epoch, t_s, acceleration=True)

    variants = {"bare SatrecArray.sgp4 (TEME km)": bare, "propagate_ecef r,v": ecef_rv,
                "propagate_ecef r,v,a": ecef_rva}
    times: dict[str, list[float]] = {name: [] for name in variants}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for fn in variants.values():  # warm-up
            fn()
        for _ in range(args.repeats):
            for name, fn in variants.items():
                start = time.perf_counter()
                fn()
                times[name].append(time.perf_counter() - start)

    n = args.sats * args.epochs
    reference = statistics.median(times["bare SatrecArray.sgp4 (TEME km)"])
    print(f"{args.sats} satellites x {args.epochs} epochs = {n} satellite-epochs, median of {args.repeats}")
    print(f"{'variant':34s} {'median s':>9s} {'sat-epochs/s':>13s} {'ratio':>6s}")
    for name, values in times.items():
        median = statistics.median(values)
        print(f"{name:34s} {median:9.4f} {n / median:13.3e} {median / reference:6.2f}x")
    ratio = statistics.median(times["propagate_ecef r,v,a"]) / reference
    print(f"goal <= 1.50x for the full wrapper: {'met' if ratio <= 1.5 else 'NOT met'} ({ratio:.2f}x)")


if __name__ == "__main__":
    main()
