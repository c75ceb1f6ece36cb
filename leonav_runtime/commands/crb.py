"""`leonav crb`: position bound of a static receiver from Starlink Doppler-rate vs satellite count."""
from __future__ import annotations

import argparse
import copy
import math
from pathlib import Path

import numpy as np

from leonav_runtime.common import output
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.scenarios.load import load_scenario, scenario_from_dict

OBSERVABLES = ("doppler_rate", "doppler", "ofdm_range_diff")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "crb",
        help="snapshot CRB of a static receiver's position vs number of Starlink satellites",
        description=(
            "For a static receiver at the scenario's site, stack the Jacobians of a Starlink observable "
            "(default: Doppler-rate) with respect to position over the scenario window for the N highest "
            "satellites and print sqrt(CRB) of the position versus N, next to the filter's PCRB with a "
            "vague position prior and negligible process noise (the two must agree). Use --tle with real "
            "element sets (a GPS file is needed too when the scenario's modes use GPS)."
        ),
    )
    p.add_argument("scenario", nargs="?", default="paper", help="scenario file or built-in name (default paper)")
    p.add_argument("--tle", action="append", default=[], metavar="FILE",
                   help="element-set file (repeatable); default: the scenario's elements")
    p.add_argument("--start", default=None, metavar="ISO-UTC", help="scenario epoch override")
    p.add_argument("--observable", choices=OBSERVABLES, default="doppler_rate",
                   help="Starlink observable whose position information is bounded (default %(default)s; "
                        "doppler is reported without the PCRB column because its LO offset is a nuisance state)")
    output.add_out_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from leonav_runtime.simulation import simulate
    from leonav_runtime.sweep import crb, montecarlo as mc

    base = load_scenario(args.scenario)
    raw = copy.deepcopy(base.raw)
    if args.tle:
        raw["elements"] = {"source": "files", "files": [str(Path(f).resolve()) for f in args.tle]}
    if args.start:
        raw.setdefault("time", {})["epoch"] = args.start
    raw.setdefault("monte_carlo", {})["modes"] = ["leo-alpha+imu"]  # GPS elements not needed
    scn = scenario_from_dict(raw, source=base.source, base_dir=Path(base.source).parent)
    out_dir = output.results_dir(args.out, f"crb-{scn.name}")
    setup, nav = mc.setup_for(scn)
    mode = {"doppler_rate": "leo-alpha+imu", "doppler": "leo-doppler+alpha+imu",
            "ofdm_range_diff": "leo-ofdm+imu"}[args.observable]
    rows = []
    print(f"{scn.name}: static receiver at {math.degrees(scn.lat_rad):.7f}, {math.degrees(scn.lon_rad):.7f}, "
          f"{scn.alt_m:g} m; {scn.duration_s:g} s at {scn.starlink['rate_hz']:g} Hz; {args.observable}; "
          f"elements: {', '.join(map(str, scn.element_files)) or 'built-in'}")
    print(f"{'N':>4} {'sqrt(CRB) 3D m':>15} {'E':>8} {'N':>8} {'U':>8} {'PCRB 3D m':>10}")
    for count in scn.starlink["counts"]:
        S = crb.snapshot_crb(setup, nav, count, args.observable)
        if args.observable == "doppler":
            # the LO offset is a nuisance shared by all Doppler measurements: the PCRB carries it
            B = None
        else:
            B = crb.pcrb_static(setup, nav, count, mode)
        sd = np.sqrt(np.diag(S))
        b3 = float(np.sqrt(np.trace(B))) if B is not None else math.nan
        rows.append([count, float(np.sqrt(np.trace(S))), *map(float, sd), b3])
        print(f"{count:4d} {rows[-1][1]:15.2f} {sd[0]:8.2f} {sd[1]:8.2f} {sd[2]:8.2f} {b3:10.2f}")
    if not rows:
        raise UserInputError("no satellite counts to evaluate")
    output.write_csv(out_dir / "crb.csv", ["count", "sqrt_crb_3d_m", "sqrt_crb_e_m", "sqrt_crb_n_m",
                                          "sqrt_crb_u_m", "sqrt_pcrb_static_3d_m"], rows)
    from leonav_runtime.common.provenance import provenance

    output.write_json(out_dir / "crb.json", {
        "provenance": provenance(scn.raw), "scenario": scn.name, "epoch_utc": scn.epoch_utc, "duration_s": scn.duration_s,
        "observable": args.observable, "sigma": simulate.noise_sigma(scn, args.observable),
        "elements": [str(f) for f in scn.element_files] or "built-in",
        "rows": [dict(zip(["count", "sqrt_crb_3d_m", "e_m", "n_m", "u_m", "sqrt_pcrb_static_3d_m"], r))
                 for r in rows]})
    print(f"results: {out_dir}/ (crb.csv, crb.json)")
    return 0
