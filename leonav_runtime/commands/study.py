"""`leonav study STUDY.toml`: RMSE and sqrt(PCRB) over a grid of one or two scenario fields."""
from __future__ import annotations

import argparse

from leonav_runtime.common import output
from leonav_runtime.sweep.executors import add_executor_arguments
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.study import shipped_studies


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "study",
        help="sensitivity study: RMSE and sqrt(PCRB) over one or two varied scenario fields",
        description=(
            "Run a study file: a base scenario, fixed overrides ([set], --set) and one or two varied "
            "scenario fields ([[vary]] key = \"section.key\", values = [...], in the scenario file's "
            "units). Every cell runs the study's modes at its Starlink count with the same trial seeds. "
            "Writes study.csv, study.json, study.png (heat map for two fields, lines for one) and "
            "report.html with time-averaged and final-epoch RMSE and sqrt(PCRB), keys with their units "
            "(position_rmse_m, position_sqrt_pcrb_m, attitude_final_rmse_deg, ...). A bare name runs a shipped "
            f"study ({', '.join(shipped_studies())})."
        ),
    )
    p.add_argument("study", metavar="STUDY", help="study TOML file or shipped study name")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario field in every cell, e.g. --set filter.initial_position_sigma_m=5 "
                        "(repeatable; value in the scenario file's unit)")
    p.add_argument("--trials", type=int, default=None, metavar="N", help="trials per cell and mode")
    add_executor_arguments(p)
    output.add_out_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from leonav_runtime.study.run import run_study, summary_table
    from leonav_runtime.study.spec import TRIALS, load_study

    if args.trials is not None and not TRIALS.lo <= args.trials <= TRIALS.hi:
        raise UserInputError(f"--trials {args.trials}: expected an integer in {TRIALS.lo:g}..{TRIALS.hi:g}")
    if args.workers is not None and args.workers < 1:
        raise UserInputError(f"--workers {args.workers}: expected an integer >= 1")
    study = load_study(args.study, args.set)
    if args.trials:
        study.trials = args.trials
    out_dir = output.results_dir(args.out, f"study-{study.name}")
    res = run_study(study, out_dir, workers=args.workers, dask_address=args.dask, progress=not args.no_progress)
    print(summary_table(study, res))
    print(f"\nresults: {out_dir}/ (report.html, study.csv, study.json, study.png, study.toml)")
    return 0
