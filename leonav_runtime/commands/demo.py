"""`leonav demo`: one short trial of every mode, in seconds."""
from __future__ import annotations

import argparse
import copy
from pathlib import Path

from leonav_runtime.common import output
from leonav_runtime.scenarios.load import load_scenario, scenario_from_dict


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "demo",
        help="one short trial of every fusion mode on the paper's scenario (seconds)",
        description=(
            "Run one trial of each mode (GPS+IMU, LEO(alpha)+IMU, GPS+LEO(alpha)+IMU, LEO(OFDM)+IMU, "
            "LEO(alpha+OFDM)+IMU, LEO(Doppler+alpha)+IMU) with the largest Starlink count of the "
            "scenario, through the generated C filter, and write the usual results folder."
        ),
    )
    p.add_argument("scenario", nargs="?", default="paper", help="scenario file or built-in name (default paper)")
    output.add_out_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from leonav_runtime.sweep.run import run_sweep, summary_table

    base = load_scenario(args.scenario)
    raw = copy.deepcopy(base.raw)
    raw.setdefault("starlink", {})["counts"] = [max(base.starlink["counts"])]
    raw.setdefault("monte_carlo", {})["trials"] = 1
    paper = raw["monte_carlo"].pop("paper_findings", False)   # one trial: the paper's verdicts mean nothing
    scn = scenario_from_dict(raw, source=base.source, base_dir=Path(base.source).parent)
    out_dir = output.results_dir(args.out, f"demo-{scn.name}")
    res = run_sweep(scn, out_dir, trials=1, workers=1, progress=False)
    print(summary_table(scn, res))
    if paper:
        print("\n(one trial per mode: the paper's findings are checked by `leonav sweep`, not here)")
    print(f"\nresults: {out_dir}/")
    return 0
