"""`leonav orbit-bound`: the PCRB when the satellites' orbit offsets are estimated with the state."""
from __future__ import annotations

import argparse
import math
import time

import numpy as np

from leonav_runtime.common import output
from leonav_runtime.common.errors import UserInputError

REPORT_TIMES_S = (10.0, 30.0, 60.0, 120.0, 240.0)


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "orbit-bound",
        help="PCRB of a mode with every Starlink satellite's orbit offset estimated (ephemeris method 1's bound)",
        description=(
            "Along the scenario's truth, the posterior CRB of the position when each Starlink satellite the mode "
            "measures carries its radial, along-track and cross-track offset from its element orbit as three "
            "states (random constants with the element age's prior sigmas), beside the filter's own PCRB with "
            "true orbits. What estimating the orbit errors with the navigation state can reach at best. Writes "
            "orbit-bound.csv (1 Hz), orbit-bound.json and orbit-bound.png."
        ),
    )
    p.add_argument("scenario", nargs="?", default="passive-phase-drive",
                   help="scenario file or built-in name (default %(default)s)")
    p.add_argument("--mode", default="leo-phase+imu", help="fusion mode (default %(default)s)")
    p.add_argument("--count", type=int, default=None, help="Starlink satellites (default: the scenario's largest count)")
    p.add_argument("--sigma-rac", action="append", default=[], metavar="R,A,C",
                   help="another case: the offsets' prior radial, along, cross sigmas in m (repeatable; e.g. an "
                        "operator ephemeris's 1.4,4.7,2.2)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario field, e.g. --set time.duration_s=60 --set "
                        "ephemeris_error.element_age_days=0.5 (repeatable; as for `leonav sweep`)")
    output.add_out_argument(p)
    p.set_defaults(func=run)


def _sigmas(text: str) -> np.ndarray:
    try:
        values = np.array([float(v) for v in text.split(",")])
    except ValueError:
        values = np.zeros(0)
    if values.size != 3 or not np.all(np.isfinite(values)) or np.any(values <= 0):
        raise UserInputError(f"--sigma-rac {text!r}: expected three positive numbers R,A,C in m (e.g. 1.4,4.7,2.2)")
    return values


def run(args: argparse.Namespace) -> int:
    from leonav_runtime.core import model
    from leonav_runtime.scenarios.load import load_scenario
    from leonav_runtime.scenarios.overrides import apply_overrides
    from leonav_runtime.simulation.orbit_truth import starlink_sigma_rac
    from leonav_runtime.sweep import montecarlo as mc, orbit_bound

    extra = [_sigmas(s) for s in args.sigma_rac]
    scn, _ = apply_overrides(load_scenario(args.scenario), sets=args.set)
    model.parse_mode(args.mode)
    count = int(args.count if args.count is not None else max(scn.starlink["counts"]))
    if count < 1:
        raise UserInputError(f"--count {count}: expected at least 1 satellite")
    age_h = max(24.0 * scn.realism["ephemeris"]["element_age_days"], 1.0)   # the sigma model's own floor
    sig = starlink_sigma_rac(scn.realism["ephemeris"])
    cases = [("true orbits", None), (f"offsets estimated, element sets {age_h:g} h old", sig)]
    cases += [(f"offsets estimated, prior {s[0]:g}/{s[1]:g}/{s[2]:g} m", s) for s in extra]
    out_dir = output.results_dir(args.out, f"orbit-bound-{scn.name}")
    print(f"{scn.name}: {args.mode}, {count} satellites, {scn.duration_s:g} s")
    setup, nav = mc.setup_for(scn)
    recs, x_lin = orbit_bound.records_on_truth(setup, nav, args.mode, count)
    t = recs["t"]
    grid = np.arange(1.0, t[-1] + 1e-9, 1.0)
    at = np.searchsorted(t, grid, side="right") - 1
    report = [x for x in REPORT_TIMES_S if x < t[-1]] + [float(t[-1])]
    rows_of = np.searchsorted(t, report, side="right") - 1
    results, columns = [], []
    print(f"{'case':48s} " + " ".join(f"{x:>7g} s" for x in report) + "   satellites")
    for name, sig in cases:
        c0 = time.process_time()
        b = orbit_bound.bound(recs, x_lin, setup.P0, setup.params, nav, sig)
        cpu = time.process_time() - c0
        columns.append(b.position_m[at])
        figures = [float(b.position_m[r]) for r in rows_of]
        print(f"{name:48s} " + " ".join(f"{v:9.3f}" for v in figures) + f"   {b.sat_id.size:4d}   ({cpu:.0f} s CPU)",
              flush=True)
        orbit_rms = np.sqrt(np.mean(b.orbit_sigma_m**2, axis=0)) if b.sat_id.size else [math.nan] * 3
        results.append({"case": name, "prior_sigma_rac_m": None if sig is None else [float(v) for v in sig],
                        "final_position_m": figures[-1], "position_m_at": dict(zip(map(str, report), figures)),
                        "satellites": int(b.sat_id.size), "measurements": b.measurements,
                        "orbit_sigma_rms_rac_m_at_last_measurement": [float(v) for v in orbit_rms],
                        "cpu_s": cpu})
    output.write_csv(out_dir / "orbit-bound.csv", ["t_s"] + [f"sqrt_pcrb_position_m ({n})" for n, _ in cases],
                     [[float(g), *map(float, c)] for g, c in zip(grid, np.array(columns).T)])
    from leonav_runtime.common.provenance import provenance

    output.write_json(out_dir / "orbit-bound.json", {
        "provenance": provenance(scn.raw), "scenario": scn.name, "mode": args.mode, "count": count,
        "duration_s": scn.duration_s, "cases": results})
    _plot(out_dir / "orbit-bound.png", grid, columns, [n for n, _ in cases], f"{scn.name}, {args.mode}, {count} satellites")
    print(f"results: {out_dir}/ (orbit-bound.csv, orbit-bound.json, orbit-bound.png)")
    return 0


def _plot(path, t, columns, names, title) -> None:
    from leonav_runtime.common import plot_style

    plt = plot_style.pyplot()
    fig, ax = plt.subplots(figsize=(plot_style.COLUMN_WIDTH_IN, 2.4))
    for name, col, ls in zip(names, columns, plot_style.LINESTYLES):
        ax.semilogy(t, col, linestyle=ls, label=name)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("sqrt PCRB, 3D position (m)")
    ax.set_title(title)
    plot_style.plain_log_axis(ax)
    ax.legend(loc="upper right")
    plot_style.save(fig, path)
    plt.close(fig)
