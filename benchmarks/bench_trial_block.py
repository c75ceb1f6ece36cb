"""Benchmark: the sweep's Python per trial, outside the C loop, against another checkout's.

What a sweep task does besides the C loop: draw a block of trials (`trial_block`: sensor-error
truth, IMU increments, measurement noise) and, around each trial's C loop, write its values into
the block's stream and evaluate errors, NEES and NIS (`montecarlo._run_trials`). Both are timed
on the paper scenario's gps+imu x 5, leo-doppler+alpha+imu x 45 and leo-alpha+ofdm+imu x 25 with
blocks of --block trials (a sweep task holds 20), in CPU ms per trial (the process's clock; the C
loop's own CPU, from the worker-thread clock around each call, is subtracted). With --baseline
TREE the same measurement runs in a child process on that checkout, alternating with this tree's
in every repeat, and a fingerprint of every drawn value and every trial's errors, NEES and NIS
sums says whether both trees give the same numbers.

    python benchmarks/bench_trial_block.py [--block 20] [--repeat 5] [--baseline ../leonav-before]
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import statistics
import subprocess
import sys
import time
import warnings
from pathlib import Path

CASES = (("gps+imu", 5), ("leo-doppler+alpha+imu", 45), ("leo-alpha+ofdm+imu", 25))


def measure(block: int) -> dict:
    """Per-trial CPU ms of trial_block and of _run_trials outside its C loops, and the fingerprint."""
    import numpy as np

    from leonav_runtime.scenarios.load import load_scenario
    from leonav_runtime.simulation import trial_block as tb
    from leonav_runtime.sweep import montecarlo as mc

    warnings.simplefilter("ignore")
    scn = load_scenario("paper")
    setup, nav = mc.setup_for(scn)
    idx = list(range(block))
    digest = hashlib.sha256()
    t_draw = t_trials = t_c = 0.0
    for mode, count in CASES:
        mc._run_trials(scn, setup, nav, mode, count, idx[:2])          # template and library warm
        t0 = time.process_time()
        blk = tb.trial_block(setup, mode, count, [mc.trial_rng(scn.seed, i) for i in idx], nav)
        t1 = time.process_time()
        results, c_s = mc._run_trials(scn, setup, nav, mode, count, idx)
        t_draw, t_trials, t_c = t_draw + t1 - t0, t_trials + time.process_time() - t1, t_c + c_s
        for a in (blk.u, blk.z, blk.f_b, blk.x0, *blk.errors.values()):
            digest.update(np.ascontiguousarray(a).tobytes())
        for r in results:
            digest.update(r.err.tobytes() + r.nees.tobytes())
            digest.update(repr((sorted(r.nis_sum.items()), sorted(r.nis_count.items()))).encode())
    n = block * len(CASES)
    return {"draws_ms": 1e3 * t_draw / n, "outside_c_ms": 1e3 * (t_trials - t_c) / n, "c_ms": 1e3 * t_c / n,
            "fingerprint": digest.hexdigest()[:16]}


def _child(tree: Path, block: int) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run([sys.executable, __file__, "--child", "--block", str(block)], env=env, cwd=tree,
                         capture_output=True, text=True, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--block", type=int, default=20, help="trials per block (a sweep task: 20)")
    ap.add_argument("--repeat", type=int, default=5, help="repeats, each tree once per repeat")
    ap.add_argument("--baseline", type=Path, default=None, metavar="TREE", help="another checkout to compare")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(measure(args.block)))
        return
    here = Path(__file__).resolve().parents[1]
    trees = {"this tree": here} | ({"baseline": args.baseline.resolve()} if args.baseline else {})
    runs: dict[str, list[dict]] = {name: [] for name in trees}
    print(f"load average {os.getloadavg()[0]:.2f}; blocks of {args.block} trials; {args.repeat} repeats")
    for k in range(args.repeat):
        for name, tree in trees.items():
            runs[name].append(_child(tree, args.block))
        print(f"  repeat {k + 1}/{args.repeat}: " + "; ".join(
            f"{name} draws {r[-1]['draws_ms']:.3f}, outside C {r[-1]['outside_c_ms']:.3f} ms" for name, r in runs.items()),
              flush=True)
    print("CPU ms per trial (min / median of the repeats): draws | all outside the C loop (draws included) | C loop")
    for name, r in runs.items():
        cols = [(min(x[key] for x in r), statistics.median(x[key] for x in r))
                for key in ("draws_ms", "outside_c_ms", "c_ms")]
        print(f"  {name:10s} " + " | ".join(f"{lo:.3f} / {med:.3f}" for lo, med in cols)
              + f"   fingerprint {r[0]['fingerprint']}")
    if args.baseline:
        a, b = runs["this tree"], runs["baseline"]
        for key, label in (("draws_ms", "draws"), ("outside_c_ms", "all outside the C loop")):
            ratio = statistics.median(x[key] for x in a) / statistics.median(x[key] for x in b)
            print(f"  {label}: this tree / baseline = {ratio:.2f} (medians)")
        print(f"  same numbers: {a[0]['fingerprint'] == b[0]['fingerprint']}")
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
