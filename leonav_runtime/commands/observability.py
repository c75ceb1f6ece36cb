"""`leonav observability`: which states each sensor combination observes, under which motion, how weakly."""
from __future__ import annotations

import argparse
import copy
import math
from pathlib import Path

import numpy as np

from leonav_runtime.common import output
from leonav_runtime.common.errors import UserInputError


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "observability",
        help="which error states each mode observes, per motion class, and along a scenario",
        description=(
            "Structural observability of the error-state filter from the same symbolic models it is "
            "generated from: for every mode (the filter's observable sets plus GNSS position fixes) and "
            "motion class (static, constant velocity, constant turn, accelerating) the rank of the "
            "discrete-time local observability matrix at generic points, its unobservable directions "
            "named as combinations of states, weak directions and the steps needed. Then, along a "
            "scenario's trajectory and satellites, the information (observability Gramian) over time: "
            "singular values, weakest directions, time until each state is known to a target sigma. "
            "Writes a table (printed and CSV), PNG figures and JSON. The symbolic part needs casadi."
        ),
    )
    from leonav_runtime.observability.naming import analysis_modes

    p.add_argument("--modes", nargs="+", metavar="MODE", default=None,
                   help=f"modes to analyse (default: all: {', '.join(analysis_modes())}; or any mode name)")
    p.add_argument("--motions", nargs="+", metavar="MOTION", default=None,
                   help="motion classes: static constant-velocity constant-turn accelerating (default: all)")
    p.add_argument("--scenario", default="paper", metavar="NAME",
                   help="scenario file or built-in name for the run-along analysis (default paper; 'none' skips)")
    p.add_argument("--count", type=int, default=None, metavar="N",
                   help="Starlink satellites in the scenario run (default: the scenario's smallest count)")
    p.add_argument("--target", action="append", default=[], metavar="NAME=SIGMA",
                   help="target sigma (SI) of a component or block for the time-to-target column, e.g. "
                        "dtheta_z=0.0175 or dp=1 (repeatable; default: the prior sigma)")
    p.add_argument("--steps", type=int, default=None, metavar="N", help="steps of the structural analysis (default 30)")
    p.add_argument("--draws", type=int, default=2, metavar="N", help="generic points per case (default 2)")
    p.add_argument("--seed", type=int, default=None, metavar="N", help="seed of the generic points")
    output.add_out_argument(p)
    p.set_defaults(func=run)


def _targets(items: list[str]) -> dict[str, float]:
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            sep = ""
        if not sep or not name.strip():
            raise UserInputError(f"--target {item!r}: expected NAME=SIGMA with SIGMA in SI units, e.g. dp=1")
    return out


def _targets_text(targets: dict[str, float], comps) -> str:
    """The time-to-target header's description of the targets, with units, e.g.
    "targets: dtheta 0.0175 rad; other states: their prior sigma"."""
    if not targets:
        return "target: each state's prior sigma"
    units = {}
    for c in comps:
        units.setdefault(c.name, c.unit)
        units.setdefault(c.block, c.unit)
    named = ", ".join(f"{k} {v:g} {units[k]}" if units.get(k) else f"{k} {v:g}" for k, v in targets.items())
    return f"targets: {named}; other states: their prior sigma"


def run(args: argparse.Namespace) -> int:
    from leonav_runtime import observability as obs

    try:
        from leonav.codegen import observability as symbolic  # casadi + models/: the codegen-side path
    except ImportError as exc:
        raise UserInputError(f"the structural analysis needs casadi and the models/ package ({exc})") from None

    modes = obs.analysis_modes()
    if args.modes:   # any mode name: the default list's, or other words of the registry
        from leonav_runtime.core import model

        modes = {m: modes[m] if m in modes else model.parse_mode(m, where="--modes:").suffixes for m in args.modes}
    motions = args.motions or list(symbolic.MOTIONS)
    unknown = [m for m in motions if m not in symbolic.MOTIONS]
    if unknown:
        raise UserInputError(f"--motions: unknown class(es) {', '.join(unknown)}; expected some of "
                             f"{', '.join(symbolic.MOTIONS)}")
    if args.draws < 1 or (args.steps is not None and args.steps < 1):
        raise UserInputError("--draws and --steps: expected integers >= 1")
    targets = _targets(args.target)
    out_dir = output.results_dir(args.out, "observability")

    kw = {"n_draws": args.draws}
    if args.steps is not None:
        kw["n_steps"] = args.steps
    if args.seed is not None:
        kw["seed"] = args.seed
    res = symbolic.analyze(modes, motions, **kw)
    summaries = [c.summary() for c in res["cases"]]
    comps = [c.name for c in symbolic.components()]
    print(f"structural observability ({len(comps)} error states: {', '.join(comps)}); "
          f"{res['settings']['n_steps']} steps of {res['settings']['dt_s']:g} s, rank threshold "
          f"{symbolic.REL_TOL:g}, weak below {symbolic.WEAK_TOL:g} (relative); {res['seconds']:.1f} s")
    print(obs.format_structural_table(summaries))
    output.write_csv(out_dir / "structural.csv", obs.STRUCTURAL_HEADER, obs.structural_rows(summaries))
    output.write_csv(out_dir / "structural_index.csv", ["mode", "motion", *comps],
                     [[s["mode"], s["motion"], *[s["observability_index"][c] for c in comps]] for s in summaries])

    runs, scenario_info = _scenario_runs(args, modes, targets)
    if runs:
        print(f"\n{scenario_info['name']}: seconds until the measurements alone give sigma <= target "
              f"({_targets_text(targets, symbolic.components())}; '-': not within the run; "
              f"{scenario_info['count']} Starlink satellites)")
        print(obs.format_time_to_target(runs))
        print(f"\n{scenario_info['name']}: at the end of the run (information in units of the prior's)")
        for r in runs:
            null = [_two_terms(w) for w in r["weakest_final"] if w["unobservable"]]
            weak = [f"{w['label']} {w['information']:.2g}" for w in r["weakest_final"] if not w["unobservable"]]
            print(f"{r['mode']:22s} rank {int(r['rank'][-1])}/{len(r['components'])}; unobservable: "
                  f"{'; '.join(null) or 'none'}; weakest: {'; '.join(weak)}")
        obs.plot_singular_values(runs, out_dir / "singular_values.png",
                                 f"{scenario_info['name']}: singular values of the scaled information vs time")
        rows = []
        for r in runs:
            for k, t in enumerate(r["t_s"]):
                rows.append([r["mode"], float(t), int(r["rank"][k]), float(r["condition_observable"][k]),
                             *map(float, r["singular_values"][k])])
        output.write_csv(out_dir / "run_singular_values.csv",
                         ["mode", "t_s", "rank", "condition_observable", *[f"sv_{i + 1}" for i in range(len(comps))]],
                         rows)
        output.write_csv(out_dir / "run_time_to_target.csv",
                         ["mode", "component", "prior_sigma", "target_sigma", "time_to_target_s", "final_sigma_info",
                          "final_index", "final_pcrb_over_prior"],
                         [[r["mode"], n, float(r["prior_sigma"][i]), float(r["targets"][i]),
                           float(r["time_to_target_s"][i]), float(r["sigma_info"][-1, i]), float(r["index"][-1, i]),
                           float(r["pcrb_over_prior"][i])]
                          for r in runs for i, n in enumerate(r["components"])])
    run_by_mode = {r["mode"]: r for r in runs}
    figures = ["singular_values.png"] if runs else []
    for mode in modes:
        by_motion = {s["motion"]: np.array([s["observability_index"][c] for c in comps])
                     for s in summaries if s["mode"] == mode}
        run = run_by_mode.get(mode)
        name = f"index_{mode.replace('+', '_')}.png"
        obs.plot_index(mode, comps, by_motion, out_dir / name, None if run is None else run["index"][-1],
                       scenario_info.get("name", "scenario"))
        figures.append(name)
    from leonav_runtime.common.provenance import provenance

    output.write_json(out_dir / "observability.json", {
        "provenance": provenance(),
        "settings": res["settings"], "seconds": res["seconds"], "symbolic_build_s": res["build_s"],
        "modes": modes, "structural": summaries, "scenario": scenario_info,
        "runs": [{k: v for k, v in r.items()} for r in runs],
    })
    print(f"\nresults: {out_dir}/ (structural.csv, structural_index.csv"
          + (", run_singular_values.csv, run_time_to_target.csv" if runs else "")
          + f", {', '.join(figures)}, observability.json)")
    return 0


def _two_terms(direction: dict) -> str:
    """A direction by its two largest terms in physical units, e.g. '1 m/s^2 db_a_x +0.102 rad dtheta_y (pitch)'."""
    t = direction["terms"][:2]
    head = f"1 {t[0]['unit']} {t[0]['label']}"
    return head + "".join(f" {x['coefficient']:+.3g} {x['unit']} {x['label']}" for x in t[1:])


def _scenario_runs(args, modes: dict, targets: dict) -> tuple[list[dict], dict]:
    """Run-along analysis of the selected modes the simulator supports, on the chosen scenario."""
    if str(args.scenario).lower() == "none":
        return [], {}
    from leonav_runtime.sweep import montecarlo
    from leonav_runtime import observability as obs
    from leonav_runtime.core import model
    from leonav_runtime.scenarios.load import load_scenario, scenario_from_dict

    run_modes = [m for m in modes if all(model.simulated(o) for o in model.parse_mode(m).observables)]
    if not run_modes:
        return [], {}
    base = load_scenario(args.scenario)
    raw = copy.deepcopy(base.raw)
    raw.setdefault("monte_carlo", {})["modes"] = run_modes
    scn = scenario_from_dict(raw, source=base.source, base_dir=Path(base.source).parent)
    count = args.count if args.count is not None else min(scn.starlink["counts"])
    if count < 1:
        raise UserInputError(f"--count {count}: expected an integer >= 1")
    setup, nav = montecarlo.setup_for(scn)
    runs = []
    for mode in run_modes:
        try:
            runs.append(obs.scenario_run(scn, mode, count, targets=targets, setup=setup, nav=nav))
        except ValueError as exc:
            raise UserInputError(f"--target: {exc}") from None
    info = {"name": scn.name, "source": str(scn.source), "count": count, "duration_s": scn.duration_s,
            "modes": run_modes, "epoch_utc": scn.epoch_utc,
            "note": "information without process noise or prior, linearised on the scenario's truth; "
                    "singular values in units of the filter's prior sigma"}
    if not math.isfinite(scn.duration_s):
        raise UserInputError("scenario duration must be finite")
    return runs, info
