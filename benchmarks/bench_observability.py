"""Cost of `leonav observability`: the structural analysis of every mode x motion class.

    .venv/bin/python benchmarks/bench_observability.py [--repeats 3] [--draws 2] [--scenario paper]

Prints, each as the median of --repeats runs in this process:
- the symbolic build (F and every H of models/ as CasADi Functions), once per process;
- the analysis of all modes x motion classes (the budget is 60 s on the 2-core development
  machine) and the time per case;
- side by side, the transitions of one trajectory evaluated by one mapped call (`Function.map`,
  what the analysis does) and by one call per step, with their ratio;
- the Lie-derivative check (jtimes through the composed models) of one case;
- with --scenario, the run-along Gramian of every mode of that scenario (scenario preparation
  timed apart: it is the simulator's, shared with `leonav sweep`).
"""
from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

BUDGET_S = 60.0


def _median_time(fn, repeats: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--draws", type=int, default=2, help="generic points per case (the command's default: 2)")
    parser.add_argument("--scenario", default=None, help="also time the run-along analysis on this scenario")
    args = parser.parse_args()

    t0 = time.perf_counter()
    from leonav.codegen import observability as ob
    t_import = time.perf_counter() - t0
    t0 = time.perf_counter()
    sym = ob.symbolic()
    t_build = time.perf_counter() - t0
    from leonav_runtime import observability as ro

    modes = ro.analysis_modes()
    n_cases = len(modes) * len(ob.MOTIONS)
    t_all, res = _median_time(lambda: ob.analyze(modes, n_draws=args.draws), args.repeats)
    print(f"import codegen.observability (casadi, models/): {t_import:6.2f} s")
    print(f"symbolic build (F + {len(sym.h)} H functions):      {t_build:6.2f} s")
    print(f"all {len(modes)} modes x {len(ob.MOTIONS)} motions ({n_cases} cases, {args.draws} draws each, "
          f"{ob.N_STEPS} steps): {t_all:6.2f} s  ({1e3 * t_all / n_cases:.0f} ms per case)")
    total = t_import + t_build + t_all
    print(f"total: {total:.2f} s = {total / BUDGET_S:.1%} of the {BUDGET_S:.0f} s budget")

    traj = res["cases"][0].trajectory
    n = traj.u.shape[0]

    def mapped():
        return ob.transitions(traj, sym)

    def looped():
        return np.array([np.array(sym.step(traj.x[k], traj.u[k], traj.dt_s, traj.params)[1]) for k in range(n)])

    t_map, F1 = _median_time(mapped, max(args.repeats, 5))
    t_loop, F2 = _median_time(looped, max(args.repeats, 5))
    assert np.allclose(F1, F2, rtol=1e-12, atol=1e-12)
    print(f"{n} transitions: one mapped call {1e3 * t_map:.2f} ms, one call per step {1e3 * t_loop:.2f} ms "
          f"(ratio {t_loop / t_map:.1f})")

    c = res["cases"][0]
    t_lie, err = _median_time(lambda: ob.lie_check(c.trajectory, c.O, np.random.default_rng(0)), args.repeats)
    print(f"Lie-derivative check ({c.mode}, {c.motion}): {t_lie:.2f} s, max relative difference {err:.1e}")

    if args.scenario:
        from leonav_runtime.sweep import montecarlo
        from leonav_runtime.scenarios.load import load_scenario

        scn = load_scenario(args.scenario)
        t0 = time.perf_counter()
        setup, nav = montecarlo.setup_for(scn)
        t_setup = time.perf_counter() - t0
        t0 = time.perf_counter()
        runs = [ro.scenario_run(scn, m, setup=setup, nav=nav) for m in scn.modes]
        t_runs = time.perf_counter() - t0
        n_rec = sum(r["records"] for r in runs)
        print(f"{scn.name}: scenario preparation {t_setup:.2f} s; run-along Gramian of {len(runs)} modes "
              f"{t_runs:.2f} s ({n_rec} records, {1e6 * t_runs / max(n_rec, 1):.1f} us per record)")


if __name__ == "__main__":
    main()
