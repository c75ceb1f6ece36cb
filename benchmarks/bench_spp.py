"""`leonav spp` against RTKLIB's rnx2rtkp on the GEONET 0759 and 3040 files, side by side.

Both get the same job per file: read the RINEX observation and navigation files, solve
every epoch (GPS, 10 deg mask), write a .pos. Timed in one run, best of `--repeats`:

  rnx2rtkp      the C program, one process per file, `-p 0 -m 10 -sys G` (no atmosphere
                terms) and `-k single_brdc_saas.conf` (Klobuchar + Saastamoinen); CPU time of
                the child (user + sys) and wall time
  leonav (a)    in-process: `leonav_runtime.commands.spp.process` per file, the command's own
                work (read, signal rows, batched WLS through the generated model, RAIM,
                .pos/.csv/satellite .csv written) with the library loaded once; CPU and wall
  leonav (b)    a process per run for both files: `python -m leonav_runtime.commands.spp`
                (interpreter, NumPy and the runtime imports included)
  leonav (c)    the same through the full `leonav` CLI, which imports every subcommand
                module (their heavy imports are inside their functions)
  floor         `python -c "import numpy"`: the interpreter and NumPy alone, the least any
                Python process of the runtime costs

Child processes run with byte-code caching on (PYTHONDONTWRITEBYTECODE removed, a temporary
PYTHONPYCACHEPREFIX warmed by one untimed run), as after an install: without a cache every
run compiles the modules it imports again (~0.13 s here).

Run: `python benchmarks/bench_spp.py [--repeats N] [--out DIR]` (needs ../shared/data and
rnx2rtkp on PATH). Prints figures and ratios; writes bench_spp.json with --out.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
DATA = Path(os.environ.get("LEONAV_SHARED_DATA", REPO.parent / "shared" / "data")) / "gnss_rinex"
STATIONS = ("0759", "3040")
CONF = REPO / "tests" / "data" / "rtklib" / "single_brdc_saas.conf"


def _child_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _self_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


CHILD_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def time_process(argv: list[str], repeats: int) -> tuple[float, float]:
    """(best CPU s, best wall s) of a command run `repeats` times (after one untimed run that
    fills the byte-code cache)."""
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=CHILD_ENV)
    cpu, wall = [], []
    for _ in range(repeats):
        c0, w0 = _child_cpu(), time.perf_counter()
        subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=CHILD_ENV)
        wall.append(time.perf_counter() - w0)
        cpu.append(_child_cpu() - c0)
    return min(cpu), min(wall)


def rtklib(tmp: Path, repeats: int, atmosphere: bool) -> tuple[float, float]:
    exe = shutil.which("rnx2rtkp")
    total_cpu = total_wall = 0.0
    for st in STATIONS:
        opts = ["-k", str(CONF)] if atmosphere else ["-p", "0", "-m", "10", "-sys", "G"]
        c, w = time_process([exe, *opts, "-o", str(tmp / f"r{st}.pos"), str(DATA / f"{st}0920.05o"),
                             str(DATA / f"{st}0920.05n")], repeats)
        total_cpu += c
        total_wall += w
    return total_cpu, total_wall


def leonav_in_process(tmp: Path, repeats: int, atmosphere: bool) -> tuple[float, float]:
    from leonav_runtime.commands import spp as cmd
    from leonav_runtime.core.navfuncs import NavFunctions

    nav = NavFunctions()
    args = SimpleNamespace(elevation_mask=10.0, cn0_mask=0.0, iono="klobuchar" if atmosphere else "off",
                           tropo="saastamoinen" if atmosphere else "off", systems="G", no_raim=False, ekf=False, residuals=False,
                           q_acc=1e-10, compare=[])
    cmd.process(DATA / "07590920.05o", [str(DATA / "07590920.05n")], args, nav, tmp)  # warm (library loaded)
    cpu, wall = [], []
    for _ in range(repeats):
        c0, w0 = _self_cpu(), time.perf_counter()
        for st in STATIONS:   # each file with its own navigation file, as rnx2rtkp is run
            cmd.process(DATA / f"{st}0920.05o", [str(DATA / f"{st}0920.05n")], args, nav, tmp)
        wall.append(time.perf_counter() - w0)
        cpu.append(_self_cpu() - c0)
    return min(cpu), min(wall)


def leonav_process(tmp: Path, repeats: int, atmosphere: bool, full_cli: bool) -> tuple[float, float]:
    entry = (["-c", "import sys; from leonav_runtime.cli import main; sys.exit(main(sys.argv[1:]))", "spp"]
             if full_cli else ["-m", "leonav_runtime.commands.spp"])
    atm = [] if atmosphere else ["--iono", "off", "--tropo", "off"]
    argv = [sys.executable, *entry, *(str(DATA / f"{st}0920.05o") for st in STATIONS), "--nav",
            *(str(DATA / f"{st}0920.05n") for st in STATIONS), "--systems", "G", *atm, "--out", str(tmp)]
    return time_process(argv, repeats)


def python_floor(repeats: int) -> tuple[float, float]:
    """The interpreter and NumPy alone."""
    return time_process([sys.executable, "-c", "import numpy"], repeats)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    if shutil.which("rnx2rtkp") is None or not DATA.is_dir():
        print("needs rnx2rtkp on PATH and ../shared/data/gnss_rinex", file=sys.stderr)
        return 2
    os.chdir(REPO)
    results = {}
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        CHILD_ENV["PYTHONPYCACHEPREFIX"] = str(tmp / "pycache")
        floor = python_floor(max(2, args.repeats // 2))
        for atmosphere in (False, True):
            label = "Klobuchar + Saastamoinen" if atmosphere else "no atmosphere terms (rnx2rtkp -p 0 defaults)"
            r = rtklib(tmp, args.repeats, atmosphere)
            a = leonav_in_process(tmp, args.repeats, atmosphere)
            b = leonav_process(tmp, max(2, args.repeats // 2), atmosphere, full_cli=False)
            c = leonav_process(tmp, max(2, args.repeats // 2), atmosphere, full_cli=True)
            results[label] = {"rnx2rtkp": r, "leonav_in_process": a, "leonav_process_lean": b, "leonav_cli": c,
                              "python_numpy_floor": floor}
            print(f"\nboth files (2 x 120 epochs, GPS, 10 deg mask), {label}; best of {args.repeats}:")
            print(f"  {'':38s} {'CPU s':>8s} {'wall s':>8s}  {'CPU ratio':>9s} {'wall ratio':>10s}")
            for name, (cpu, wall) in (("rnx2rtkp (2 processes)", r), ("leonav spp (a) in-process", a),
                                      ("leonav spp (b) python -m ...commands.spp", b), ("leonav spp (c) leonav CLI", c),
                                      ("floor: python -c 'import numpy'", floor)):
                print(f"  {name:38s} {cpu:8.3f} {wall:8.3f}  {cpu / r[0]:8.2f}x {wall / r[1]:9.2f}x")
    print("\ngoal: leonav spp <= 2x rnx2rtkp's time")
    if args.out:
        Path(args.out).mkdir(parents=True, exist_ok=True)
        (Path(args.out) / "bench_spp.json").write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
