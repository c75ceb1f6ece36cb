"""Compiler flags for the generated C, side by side: CPU per IMU step of the C loop and of a
bare generated-C loop for each set of flags, and whether the results stay bit for bit.

    python benchmarks/bench_cflags.py                  # 20 s stream, 20 repeats, 3 rounds
    python benchmarks/bench_cflags.py --seconds 60 --rounds 5

Each variant builds the library (the generated functions, one file each, plus the driver) into
its own temporary cache and loads it next to the others in this process. Flags are the
variant's after `-std=c99 -ffp-contract=off -fPIC` (what compiled.CFLAGS has besides the
optimisation flags); $LEONAV_CFLAGS is ignored here; the runtime's default row is marked. The stream is bench_filter.py's (100 Hz IMU, 8 pseudoranges at
10 Hz, 10 Doppler-rates at 1 Hz):

  (a) C loop      leonav_run over the whole stream through ctypes (what every command runs)
  (d) bare loop   benchmarks/bench_bare_loop.c: the generated functions in a minimal C loop,
                  compiled and linked with the same variant's flags and objects

Figures are process CPU time (time.process_time for (a), clock() in (d)), best of `--repeats`
runs in each of `--rounds` rounds; the rounds visit the variants in turn so that load from
other processes falls on all of them alike. "bit-identical" compares every output of (a)
(states, covariance diagonals, innovations, NIS, statuses) with the first variant's.

Variants that keep IEEE semantics change no result: -O3 (more inlining, unrolling and
vectorisation of independent lanes; no reassociation without -ffast-math), -fno-math-errno
(sqrt becomes one instruction: errno is not set for a negative argument, whose result is NaN
either way), -fno-trapping-math (no floating-point traps are enabled), -flto (inlining across
the one-file-per-function objects). No fused multiply-adds (-ffp-contract=off, also GCC's
default in ISO C mode, not clang's) is what keeps x86 and aarch64 equal. -march=native is measured for
reference only: it builds for this CPU and is not portable (opt in with LEONAV_CFLAGS).
"""
from __future__ import annotations

import argparse
import os
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

BENCH_DIR = Path(__file__).resolve().parent
sys.path.insert(0, str(BENCH_DIR))
sys.path.insert(0, str(BENCH_DIR.parent))

from bench_filter import build_stream, time_bare_c  # noqa: E402

from leonav_runtime.core import compiled, records  # noqa: E402
from leonav_runtime.core import filter as lf  # noqa: E402
from leonav_runtime.core.build_cache import load_library  # noqa: E402

BASE = ["-std=c99", "-ffp-contract=off", "-fPIC"]
NME = ["-fno-math-errno"]
# the functions a filter run spends its time in (per IMU step and per update), and the driver
HOT_PREFIXES = ("leonav_predict", "leonav_update_", "leonav_joseph", "leonav_driver")

VARIANTS: list[tuple[str, list[str], list[str] | None]] = [
    # (label, flags, flags of the cold functions or None for one set for all)
    ("-O2", ["-O2"], None),
    ("-O3", ["-O3"], None),
    ("-O2 -fno-math-errno", ["-O2", *NME], None),
    ("-O3 -fno-math-errno", ["-O3", *NME], None),
    ("-O3 -fno-math-errno -fno-trapping-math", ["-O3", *NME, "-fno-trapping-math"], None),
    ("-O3 -fno-math-errno -flto", ["-O3", *NME, "-flto"], None),
    ("-O2 -fno-semantic-interposition", ["-O2", "-fno-semantic-interposition"], None),
    ("-O3 -fno-math-errno -fno-trapping-math -fno-semantic-interposition",
     ["-O3", *NME, "-fno-trapping-math", "-fno-semantic-interposition"], None),
    ("per function: hot -O3 -fno-math-errno, rest -O2", ["-O3", *NME], ["-O2"]),
    ("-O3 -march=native (opt-in, not portable)", ["-O3", "-march=native"], None),
    ("-O3 -fno-math-errno -march=native (opt-in)", ["-O3", *NME, "-march=native"], None),
]


def _run_cc(argv: list[str]) -> None:
    proc = subprocess.run(argv, capture_output=True, text=True)
    if proc.returncode:
        raise SystemExit(f"{shlex.join(argv)} failed:\n{proc.stderr.strip()}")


def build_variant(flags: list[str], cold_flags: list[str] | None, out: Path) -> tuple[compiled.Library, float]:
    """The library built with BASE + flags (cold_flags for the functions outside HOT_PREFIXES);
    (loaded library, build CPU seconds of the compiler processes)."""
    out.mkdir(parents=True, exist_ok=True)
    ru0 = os.times()
    if cold_flags is None:
        saved = compiled.CFLAGS, os.environ.pop("LEONAV_CFLAGS", None)
        compiled.CFLAGS = tuple(BASE + flags)
        try:
            lib = compiled.load(out_dir=out)
        finally:
            compiled.CFLAGS = saved[0]
            if saved[1] is not None:
                os.environ["LEONAV_CFLAGS"] = saved[1]
    else:
        lib = _load_mixed(flags, cold_flags, out)
    ru1 = os.times()
    return lib, (ru1.children_user - ru0.children_user) + (ru1.children_system - ru0.children_system)


def _load_mixed(hot: list[str], cold: list[str], out: Path) -> compiled.Library:
    """Per-function flags: objects compiled one by one, linked and loaded as compiled.load does."""
    cc = compiled.compiler()
    version = compiled.compiler_version(cc)
    dirs = [compiled.GEN_DIR, compiled.CSRC_DIR]
    objects, keys = [], []
    for src in compiled.sources():
        flags = BASE + (hot if src.stem.startswith(HOT_PREFIXES) else cold)
        keys.append(compiled.object_key(src, dirs, flags, version))   # as the runtime's cache: rebuilt on change
        obj = out / f"{src.stem}-{keys[-1][:20]}.o"
        if not obj.exists():
            _run_cc(shlex.split(cc) + flags + [f"-I{d}" for d in dirs] + ["-c", str(src), "-o", str(obj)])
        objects.append(obj)
    so = out / f"libleonav-mixed-{compiled.library_key(keys, BASE + hot)[:20]}.so"
    if not so.exists():
        _run_cc(shlex.split(cc) + list(compiled.LDFLAGS) + BASE + hot + [str(o) for o in objects] + ["-o", str(so)]
                + list(compiled.LIBS))
    info = compiled.BuildInfo(so, "mixed", cc, version, BASE + hot, list(compiled.LDFLAGS), objects)
    lib = load_library(so, cc)
    layout = compiled.load_layout()
    compiled.check_layout(lib, layout)
    compiled._declare(lib)
    return compiled.Library(lib, layout, info, int(lib.leonav_work_size()), compiled.measurement_ids(layout))


def time_a(lib: compiled.Library, recs, x0, P0, params, repeats: int) -> tuple[float, object]:
    """Best process CPU seconds of leonav_run over the stream, and the last result."""
    best, res = float("inf"), None
    for _ in range(repeats):
        t0 = time.process_time()   # the filter's set-up included, as bench_filter.py times (a)
        res = lf.EKF(x0, P0, params, library=lib).run(recs)
        best = min(best, time.process_time() - t0)
    return best, res


def _outputs(res) -> list[np.ndarray]:
    return [np.asarray(getattr(res, k)) for k in ("x", "P_diag", "y", "S", "nis", "status") if hasattr(res, k)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=20.0, help="stream length, s (default 20: 2,000 IMU steps)")
    ap.add_argument("--repeats", type=int, default=20, help="runs per variant and round; the best counts")
    ap.add_argument("--rounds", type=int, default=3, help="rounds over all variants (default 3)")
    ap.add_argument("--cache", metavar="DIR", help="keep the variants' builds here (default: a temporary folder; "
                                                    "a build found there shows 0 build CPU)")
    a = ap.parse_args()
    load = os.getloadavg()
    base_lib = compiled.load()
    recs, _, x0, P0, params = build_stream(base_lib, a.seconds)
    n_imu = int(np.count_nonzero(recs["kind"] == records.KIND_IMU))
    gate = lf.CHI2_1DOF_999
    cc = compiled.compiler()
    print(f"{compiled.compiler_version(cc)}; {os.cpu_count()} cores, load average {load[0]:.2f} / {load[1]:.2f} / "
          f"{load[2]:.2f} at start; stream {a.seconds:g} s, {recs.size} records, {n_imu} IMU steps")
    with tempfile.TemporaryDirectory(prefix="leonav-cflags-") as tmp:
        cache = Path(a.cache) if a.cache else Path(tmp)
        libs, build_cpu = {}, {}
        for i, (label, flags, cold) in enumerate(VARIANTS):
            print(f"building {label} ...", flush=True)
            libs[label], build_cpu[label] = build_variant(flags, cold, cache / f"v{i}")
        best_a = {v[0]: float("inf") for v in VARIANTS}
        best_d = dict(best_a)
        results, finals_d = {}, {}
        for r in range(a.rounds):
            print(f"round {r + 1}/{a.rounds} ...", flush=True)
            (Path(tmp) / f"d{r}").mkdir()
            for label, _, _ in VARIANTS:
                t, results[label] = time_a(libs[label], recs, x0, P0, params, a.repeats)
                best_a[label] = min(best_a[label], t)
                t, finals_d[label] = time_bare_c(libs[label].build, recs, x0, P0, params, gate, a.repeats,
                                                 Path(tmp) / f"d{r}")
                best_d[label] = min(best_d[label], t)
    ref_label = VARIANTS[0][0]
    ref = _outputs(results[ref_label])
    us = lambda s: s / n_imu * 1e6  # noqa: E731
    print(f"\nCPU per IMU step (predict + its share of 0.8 pseudorange and 0.1 Doppler-rate updates), best of "
          f"{a.repeats} x {a.rounds}; bit-identical: every output of (a) against {ref_label}")
    print(f" {'flags after -std=c99 -ffp-contract=off -fPIC':70s} | (a) C loop us | vs {ref_label} | (d) bare us | (a)/(d) | "
          "bit-identical | library kB | build CPU s")
    default = sorted(compiled.CFLAGS)
    for label, flags, cold in VARIANTS:
        if cold is None and sorted(BASE + flags) == default:
            label_shown = label + " (default)"
        else:
            label_shown = label
        # bytes, not values: NaN (no innovation on IMU rows) must match NaN, and -0.0 must stay -0.0
        same = all(u.tobytes() == v.tobytes() for u, v in zip(_outputs(results[label]), ref))
        same_d = finals_d[label].tobytes() == finals_d[ref_label].tobytes()
        size = libs[label].build.library.stat().st_size / 1024
        print(f" {label_shown:70s} | {us(best_a[label]):13.3f} | {best_a[label] / best_a[ref_label]:6.3f} | "
              f"{us(best_d[label]):11.3f} | {best_a[label] / best_d[label]:7.3f} | {str(same and same_d):13s} | "
              f"{size:10.0f} | {build_cpu[label]:11.1f}")
    print(f"\nruntime defaults now: {' '.join(compiled.CFLAGS)} (leonav_runtime/core/compiled.py; add flags with "
          "LEONAV_CFLAGS)")


if __name__ == "__main__":
    main()
