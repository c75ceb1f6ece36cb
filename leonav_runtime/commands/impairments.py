"""`leonav impairments`: beacon association and |delta alpha| under receiver/capture impairments."""
from __future__ import annotations

import argparse

from leonav_runtime.common import output
from leonav_runtime.common.errors import UserInputError


def register(subparsers) -> None:
    from leonav_runtime.beacons.impairments import SETS

    p = subparsers.add_parser(
        "impairments",
        help="beacon association correctness and |delta alpha| on synthetic captures with real-receiver impairments",
        description=(
            "Write synthetic Starlink beacon captures (five satellites, 6 s, 400 kS/s cu8) with each "
            "receiver/capture impairment alone and all together (IQ imbalance, DC spike, 8-bit clipping, "
            "LNB LO phase noise and temperature drift, SDR ppm drift, a strong CW interferer, overlapping "
            "combs), run the beacon pipeline on them and score every ridge against the truth. Writes "
            "impairments.csv, impairments.json and impairments.png."
        ),
    )
    p.add_argument("--tle", action="append", default=[], metavar="FILE",
                   help="Starlink element-set file (repeatable); default: the built-in Walker shells at --start")
    p.add_argument("--start", default="2026-02-23T06:00:00Z", metavar="ISO-UTC",
                   help="first capture start (later ones 37 min apart); default 2026-02-23T06:00:00Z")
    p.add_argument("--cn0", action="append", type=float, default=None, metavar="DBHZ",
                   help="beacon C/N0 per tone, dB-Hz (repeatable; default 30)")
    p.add_argument("--trials", type=int, default=10, metavar="N", help="captures per set and C/N0 (default 10)")
    p.add_argument("--sets", default="all", metavar="A,B",
                   help=f"impairment sets, comma-separated, or 'all' for every one ({', '.join(SETS)})")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    output.add_out_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import warnings

    from leonav_runtime.beacons import impairment_study as st
    from leonav_runtime.beacons.predict import Site
    from leonav_runtime.orbits import default_elements, group_by_constellation, load_elements
    from leonav_runtime.common.utc import parse_utc

    names = list(st.SETS) if args.sets == "all" else [s.strip() for s in args.sets.split(",")]
    bad = [n for n in names if n not in st.SETS]
    if bad:
        raise UserInputError(f"--sets {bad[0]!r}: expected 'all' or a comma-separated list of {', '.join(st.SETS)}")
    if not 1 <= args.trials <= 1000:
        raise UserInputError(f"--trials {args.trials}: expected 1..1000")
    cn0s = args.cn0 or [30.0]
    if not all(10.0 <= c <= 80.0 for c in cn0s):
        raise UserInputError(f"--cn0 {cn0s}: expected values in 10..80 dB-Hz")
    start = parse_utc(args.start, "--start", require_zone=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if args.tle:
            elements = group_by_constellation([load_elements(f) for f in args.tle]).get("starlink")
            if elements is None:
                raise UserInputError(f"--tle {', '.join(args.tle)}: no Starlink element sets found")
        else:
            elements = default_elements(start)["starlink"]
    site = Site.from_degrees(43.0848638, -77.6786127, 170.0)   # the paper's site (RIT)
    bar = None
    if not args.no_progress:
        from leonav_runtime.common.progress import progress as make_progress

        bar = make_progress(len(names) * len(cn0s) * args.trials, "impairments", "capture")
    rows = st.run(elements, site, start, names, cn0s, args.trials, progress=bar.update if bar else None)
    if bar:
        bar.close()
    out_dir = output.results_dir(args.out, "impairments")
    st.write_results(out_dir, rows, {"tle": args.tle or "built-in Walker shells", "start_utc": start,
                                     "site": "43.0848638, -77.6786127, 170 m", "match_hz": st.MATCH_HZ})
    print(f"{'impairments':18s} {'C/N0':>5s} {'ridges':>6s} {'correct':>8s} {'wrong':>5s} {'missed':>6s} "
          f"{'sats found':>10s} {'median |da|':>11s}")
    for r in rows:
        print(f"{r['impairments']:18s} {r['cn0_dbhz']:5.1f} {r['ridges']:6d} {100 * r['correct_fraction']:7.1f}% "
              f"{r['wrong']:5d} {r['missed']:6d} {100 * r['satellites_found_fraction']:9.0f}% "
              f"{r['median_abs_dalpha_hz_s']:8.2f} Hz/s")
    print(f"\nresults: {out_dir}/ (impairments.csv, impairments.json, impairments.png)")
    return 0
