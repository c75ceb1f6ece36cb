"""`leonav run DATASET.toml`: a real GNSS/INS dataset through the filter, scored, trajectories out."""
from __future__ import annotations

import argparse
import math
from pathlib import Path

from leonav_runtime.common import output
from leonav_runtime.common.errors import UserInputError


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "run",
        help="run a GNSS/INS dataset described by a TOML file (e.g. cpet_run3) and score it",
        description=(
            "Read the IMU, GNSS and reference files a dataset description names (columns, units, axes, time "
            "offset, lever arm; docs/datasets.md), align (leveling at rest, heading from the GNSS course), run "
            "the generated filter in every mode of [filter] modes (fix+imu, +nhc, +zupt) and with 30 s GPS "
            "outages, and score at the reference epochs. Writes metrics.json, errors.csv, trajectory_<mode>.csv/"
            ".pos/.kml/.gpx, error_vs_time.png (outages shaded), error_cdf.png and trajectory.png. A bare name "
            "(cpet_run3) picks a description shipped with leonav (listed in docs/datasets.md)."),
    )
    p.add_argument("dataset", metavar="DATASET.toml", help="dataset description file, or a shipped name")
    add_reference_arguments(p, heights=True)
    p.add_argument("--until", type=float, default=None, metavar="S",
                   help="only the first S seconds after the first GNSS fix (quick look)")
    p.add_argument("--no-outages", action="store_true", help="skip the outage runs")
    output.add_out_argument(p)
    p.set_defaults(func=run)


def add_reference_arguments(p, heights: bool) -> None:
    """--reference FILE and how to read it (also `leonav replay`)."""
    p.add_argument("--reference", metavar="FILE", default=None,
                   help="score against this file: RTKLIB .pos, or CSV with --reference-crs")
    p.add_argument("--reference-crs", default="llh", metavar="CRS",
                   help="CRS of a --reference CSV: llh (deg, deg, m), ecef (m) or EPSG:<code> (default %(default)s)")
    p.add_argument("--reference-columns", default="0,1,2,3", metavar="T,A,B,C",
                   help="0-based columns of unix time and the 3 coordinates in a --reference CSV (default %(default)s)")
    if heights:
        p.add_argument("--reference-height-datum", default="ellipsoid", choices=("ellipsoid", "msl"),
                       help="heights of a --reference CSV: WGS84 ellipsoidal, or above mean sea level (plus the "
                       "description's [gnss] geoid_separation_m) (default %(default)s)")


def reference_options(args) -> dict | None:
    """The `[reference]`-like mapping of the --reference options, or None without --reference."""
    if args.reference is None:
        return None
    if not Path(args.reference).is_file():
        raise UserInputError(f"--reference {args.reference}: file not found; expected an RTKLIB .pos or a CSV")
    try:
        cols = [int(c) for c in args.reference_columns.split(",")]
    except ValueError:
        cols = []
    if len(cols) != 4 or min(cols) < 0:
        raise UserInputError(f"--reference-columns: {args.reference_columns!r}: expected 4 column indices T,A,B,C")
    crs = args.reference_crs
    if crs not in ("llh", "ecef") and not (crs.startswith("EPSG:") and crs[5:].isdigit()):
        raise UserInputError(f"--reference-crs: {crs!r}: expected llh, ecef or EPSG:<code>")
    fmt = "pos" if args.reference.endswith(".pos") else "csv"
    return {"path": args.reference, "format": fmt, "crs": crs, "delimiter": ",", "time_column": cols[0],
            "time_unit": "s", "position_columns": cols[1:], "quaternion_columns": [],
            "height_datum": getattr(args, "reference_height_datum", "ellipsoid")}


def run(args: argparse.Namespace) -> int:
    from leonav_runtime.common.progress import progress as make_progress

    from leonav_runtime.dataset import load_spec
    from leonav_runtime.dataset.evaluate import run_dataset
    from leonav_runtime.dataset.plots import fmt

    if args.until is not None and not (math.isfinite(args.until) and args.until > 0):
        raise UserInputError(f"--until: {args.until!r}: expected seconds > 0")
    spec = load_spec(args.dataset)
    ref = reference_options(args)
    out = output.results_dir(args.out, f"run-{spec.name}")
    with make_progress(None, "leonav run", leave=False, bar_format="{desc}: {elapsed}") as bar:
        def say(msg: str) -> None:
            bar.set_description_str(msg)
        m = run_dataset(spec, out, reference=ref, t_end_s=args.until, outages=not args.no_outages, progress=say)
    print(f"run {spec.name} -> {out}  (reference: {m['reference']}, {m['reference_epochs']} epochs)")
    print(f"  {'':<20} {'horiz RMSE m':>12} {'vert m':>7} {'3D m':>6} {'yaw deg':>8} {'fix NIS':>8} {'us/IMU':>7}"
          "  outage end m (hold last fix)")
    for label, g in (("GPS alone (hold)", m["gps_alone"]), ("GPS alone (interp.)", m["gps_alone_interpolated"])):
        print(f"  {label:<20} {fmt(g['rmse_horizontal_m']):>12} {fmt(g['rmse_vertical_m']):>7} "
              f"{fmt(g['rmse_3d_m']):>6}")
    for mode, s in m["modes"].items():
        o = s.get("outages", {}).get("outages", [])
        outs = " ".join(f"{r['filter_horizontal_m']:.1f}({r['hold_last_fix_horizontal_m']:.1f})" for r in o
                        if "filter_horizontal_m" in r)
        print(f"  {mode:<20} {fmt(s['rmse_horizontal_m']):>12} {fmt(s['rmse_vertical_m']):>7} {fmt(s['rmse_3d_m']):>6} "
              f"{fmt(s.get('rmse_yaw_deg_after_skip'), 2):>8} {fmt(s['fix_nis_mean']['all'], 2):>8} "
              f"{s['us_per_imu_step']:>7.2f}  {outs}")
        if "fix_latency_s" in s:
            lat = s["fix_latency_s"]
            print(f"  {'':<20} fix latency estimated: {lat['value'] * 1e3:.1f} +- {lat['sigma'] * 1e3:.1f} ms")
    a = m.get("alignment", {})
    if a:
        print(f"  alignment: {a.get('kind', '?')} at {a.get('start_s', 0):.2f} s; {a.get('gyro_bias_source', '')}")
    for note in m.get("notes", []):
        if note.startswith("WARNING"):
            print(f"  {note}")
    for goal, v in m["summary"].items():
        if isinstance(v, dict):
            state = "not scored" if v["met"] is None else "met" if v["met"] else "NOT met"
            values = ", ".join(f"{k}={fmt(x) if isinstance(x, float) else x}" for k, x in v.items() if k != "met")
            print(f"  goal {goal}: {state} ({values})")
    return 0
