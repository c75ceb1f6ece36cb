"""`leonav sweep [SCENARIO]`: the paper's Monte Carlo study (the README's main job)."""
from __future__ import annotations

import argparse

from leonav_runtime.common import output
from leonav_runtime.sweep.executors import add_executor_arguments
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.core import model
from leonav_runtime.scenarios.load import MODES, builtin_scenarios, check_run_size, load_scenario


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "sweep",
        help="Monte Carlo RMSE vs number of Starlink satellites, every mode, with the PCRB",
        description=(
            "Run a scenario's Monte Carlo study: for every fusion mode (GPS+IMU, LEO(alpha)+IMU, "
            "GPS+LEO(alpha)+IMU, LEO(OFDM)+IMU, LEO(alpha+OFDM)+IMU, LEO(Doppler+alpha)+IMU) and every "
            "Starlink satellite count, run the generated C filter on simulated IMU, GPS pseudorange and "
            "Starlink measurements, and compare its RMSE with the posterior Cramer-Rao bound. Writes "
            "report.html, metrics.json, rmse.csv, findings.csv, rmse_vs_time.csv and PNG figures; --modes, "
            "--counts, --seed and --trials change the scenario without editing it. Without SCENARIO it runs the "
            "paper's setup (paper.toml) on the built-in constellations."
        ),
    )
    p.add_argument("scenario", nargs="?", default="paper", metavar="SCENARIO",
                   help=f"scenario TOML file or built-in name ({', '.join(builtin_scenarios())}); default paper")
    p.add_argument("--trials", type=int, default=None, metavar="N",
                   help="trials per (mode, count) (default: the scenario's [monte_carlo] trials)")
    p.add_argument("--modes", nargs="+", default=None, metavar="MODE",
                   help=f"fusion modes to run, comma- or space-separated (default: the scenario's); "
                        f"the paper's {', '.join(MODES)}, or any +-joined words of "
                        f"{model.mode_words(model.simulated)} (e.g. gps+imu+baro)")
    p.add_argument("--counts", nargs="+", default=None, metavar="N",
                   help="Starlink satellite counts, e.g. 5,10,45 or 5:45:5 (default: the scenario's [starlink] counts)")
    p.add_argument("--seed", type=int, default=None, metavar="N",
                   help="master random seed (default: the scenario's [monte_carlo] seed)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario field, e.g. --set time.epoch=2026-02-24T00:00:00Z --set "
                        "site.lat_deg=-33.87 (repeatable; value in the scenario file's unit, read by the key's type)")
    p.add_argument("--no-figures", action="store_true",
                   help="write the numbers and report.html without the PNG figures (they take ~2.5 s of a paper "
                        "sweep on 2 cores)")
    add_executor_arguments(p)
    output.add_out_argument(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from leonav_runtime.sweep.run import run_sweep, summary_table

    if args.trials is not None and args.trials < 1:
        raise UserInputError(f"--trials {args.trials}: expected an integer >= 1")
    if args.workers is not None and args.workers < 1:
        raise UserInputError(f"--workers {args.workers}: expected an integer >= 1")
    from leonav_runtime.scenarios.overrides import apply_overrides, parse_counts, split_list

    scn, _changes = apply_overrides(load_scenario(args.scenario), modes=split_list(args.modes),
                                    counts=parse_counts(args.counts), seed=args.seed, trials=args.trials,
                                    sets=args.set)
    check_run_size(scn, trials=args.trials, workers=1 if args.dask else args.workers)  # before any work
    out_dir = output.results_dir(args.out, f"sweep-{scn.name}")
    res = run_sweep(scn, out_dir, trials=args.trials, workers=args.workers, dask_address=args.dask,
                    progress=not args.no_progress, figures=not args.no_figures)
    print(summary_table(scn, res))
    from leonav_runtime.common.html_report import SWEEP_FIGURES

    files = ["report.html", "metrics.json", "rmse.csv", "findings.csv", "rmse_vs_time.csv"]
    files += [] if args.no_figures else [name for name, _ in SWEEP_FIGURES]
    print(f"\nresults: {out_dir}/ ({', '.join(files)})")
    return 0
