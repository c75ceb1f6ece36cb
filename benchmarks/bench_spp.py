"""`leonav spp` against RTKLIB's rnx2rtkp on the GEONET 0759 and 3040 files, side by side.

Both get the same job per file: read the RINEX observation and navigation files, solve
every epoch (GPS, 10 deg mask), write a .pos. Paired in one run: every repeat times
rnx2rtkp and then each leonav variant right after it, so a change of the machine's load
hits both sides of a ratio alike; figures are the best of `--repeats`, ratios the median
of the per-repeat ratios (and best/best beside it).

  rnx2rtkp      the C program, one process per file, `-p 0 -m 10 -sys G` (no atmosphere
                terms) and `-k single_brdc_saas.conf` (Klobuchar + Saastamoinen); CPU of the
                child (user + sys, getrusage of children) and wall time
  leonav (a)    in-process: `leonav_runtime.commands.spp.process` per file, the command's own
                work (read, signal rows, batched WLS through the generated model, RAIM,
                .pos/.csv written) with the library loaded once; CPU from time.process_time
  leonav (b)    a process per run for both files: `python -m leonav_runtime.commands.spp`
  leonav (c)    the same through the `leonav` command line (`leonav_runtime.cli.main`, which
                imports only the spp command's module)
  leonav (d)    (c) on Hatanaka + gzip copies of the files (.YYd.gz obs, .gz nav): the
                decompression (crx2rnx child process) included
  floor         `python -c "import numpy"`: the interpreter and NumPy alone, the least any
                Python process of the runtime costs

Child processes run with byte-code caching on (PYTHONDONTWRITEBYTECODE removed, a temporary
PYTHONPYCACHEPREFIX warmed by one untimed run), as after an install. The machine's load
(os.getloadavg) is printed before and after.

Run: `python benchmarks/bench_spp.py [--repeats N] [--out DIR] [--baseline TREE]` (needs ../shared/data and
rnx2rtkp on PATH). Prints figures and ratios; writes bench_spp.json with --out.
"""
from __future__ import annotations

import argparse
import gzip
import json
import os
import resource
import shutil
import statistics
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
CHILD_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def _child_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_process(argv: list[str], cwd: str | None = None) -> tuple[float, float]:
    """(CPU s of the child and its children, wall s) of one run of a command."""
    c0, w0 = _child_cpu(), time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=CHILD_ENV, cwd=cwd)
    return _child_cpu() - c0, time.perf_counter() - w0


def rtklib_argv(tmp: Path, atmosphere: bool) -> list[list[str]]:
    exe = shutil.which("rnx2rtkp")
    opts = ["-k", str(CONF)] if atmosphere else ["-p", "0", "-m", "10", "-sys", "G"]
    return [[exe, *opts, "-o", str(tmp / f"r{st}.pos"), str(DATA / f"{st}0920.05o"), str(DATA / f"{st}0920.05n")]
            for st in STATIONS]


def leonav_argv(tmp: Path, atmosphere: bool, entry: str, files: dict[str, tuple[Path, Path]]) -> list[str]:
    head = ([sys.executable, "-c", "import sys; from leonav_runtime.cli import main; sys.exit(main(sys.argv[1:]))",
             "spp"] if entry.startswith("cli") else [sys.executable, "-m", "leonav_runtime.commands.spp"])
    atm = [] if atmosphere else ["--iono", "off", "--tropo", "off"]
    return [*head, *(str(files[st][0]) for st in STATIONS), "--nav", *(str(files[st][1]) for st in STATIONS),
            "--systems", "G", *atm, "--out", str(tmp / f"out_{entry}")]


def compressed_copies(tmp: Path) -> dict[str, tuple[Path, Path]]:
    """{station: (Hatanaka + gzip observation file, gzip navigation file)}."""
    import hatanaka

    out = {}
    for st in STATIONS:
        obs, nav = tmp / f"{st}0920.05d.gz", tmp / f"{st}0920.05n.gz"
        obs.write_bytes(gzip.compress(hatanaka.rnx2crx((DATA / f"{st}0920.05o").read_bytes())))
        nav.write_bytes(gzip.compress((DATA / f"{st}0920.05n").read_bytes()))
        out[st] = (obs, nav)
    return out


class InProcess:
    """leonav (a): `process` per file with the library loaded once."""

    def __init__(self, tmp: Path, atmosphere: bool) -> None:
        from leonav_runtime.commands import spp as cmd
        from leonav_runtime.core.navfuncs import NavFunctions

        self.cmd, self.nav, self.tmp = cmd, NavFunctions(), tmp
        self.args = SimpleNamespace(elevation_mask=10.0, cn0_mask=0.0, iono="klobuchar" if atmosphere else "off",
                                    tropo="saastamoinen" if atmosphere else "off", systems="G", no_raim=False,
                                    ekf=False, residuals=False, q_acc=1e-10, compare=[])
        self.run()   # warm: the generated library loaded, first-call costs paid

    def run(self) -> tuple[float, float]:
        c0, w0 = time.process_time(), time.perf_counter()
        for st in STATIONS:   # each file with its own navigation file, as rnx2rtkp is run
            self.cmd.process(DATA / f"{st}0920.05o", [str(DATA / f"{st}0920.05n")], self.args, self.nav, self.tmp)
        return time.process_time() - c0, time.perf_counter() - w0


def paired(repeats: int, tmp: Path, atmosphere: bool, compressed: dict | None, baseline: Path | None = None) -> dict:
    """{variant: {"cpu": [...], "wall": [...]}} with rnx2rtkp timed right before each variant."""
    plain = {st: (DATA / f"{st}0920.05o", DATA / f"{st}0920.05n") for st in STATIONS}
    rtk = rtklib_argv(tmp, atmosphere)
    commands = {"leonav_process_lean": leonav_argv(tmp, atmosphere, "lean", plain),
                "leonav_cli": leonav_argv(tmp, atmosphere, "cli", plain)}
    if compressed:
        commands["leonav_cli_compressed"] = leonav_argv(tmp, atmosphere, "cli", compressed)
    cwd = {}
    if baseline:   # the same command line run from another checkout (its own package first on sys.path)
        commands["leonav_cli_baseline"] = leonav_argv(tmp, atmosphere, "cli_baseline", plain)
        cwd["leonav_cli_baseline"] = str(baseline)
    for name, argv in [*(("rtk", a) for a in rtk), *commands.items()]:   # untimed: byte-code cache, page cache
        run_process(argv, cwd.get(name))
    inproc = InProcess(tmp, atmosphere)
    out: dict[str, dict[str, list[float]]] = {}

    def add(name: str, cpu: float, wall: float) -> None:
        out.setdefault(name, {"cpu": [], "wall": []})
        out[name]["cpu"].append(cpu)
        out[name]["wall"].append(wall)

    def rtklib_pair() -> None:
        cpu = wall = 0.0
        for argv in rtk:
            c, w = run_process(argv)
            cpu, wall = cpu + c, wall + w
        add("rnx2rtkp", cpu, wall)

    for _ in range(repeats):
        rtklib_pair()
        add("leonav_in_process", *inproc.run())
        for name, argv in commands.items():
            rtklib_pair()
            add(name, *run_process(argv, cwd.get(name)))
    return out


def report(label: str, res: dict, floor: tuple[float, float], repeats: int) -> dict:
    """Print one table; the per-repeat ratios pair each variant with the rnx2rtkp run before it."""
    rtk = res["rnx2rtkp"]
    print(f"\nboth files (2 x 120 epochs, GPS, 10 deg mask), {label}; best of {repeats}:")
    print(f"  {'':44s} {'CPU s':>7s} {'wall s':>7s}  {'CPU ratio':>9s} {'(best/best)':>11s} {'wall ratio':>10s}")
    print(f"  {'rnx2rtkp (2 processes)':44s} {min(rtk['cpu']):7.3f} {min(rtk['wall']):7.3f}  {'1.00x':>9s}")
    # rnx2rtkp runs: [0] before in-process, then one before each command, per repeat
    per = 1 + len(res) - 2
    summary = {"rnx2rtkp": {"cpu_s": min(rtk["cpu"]), "wall_s": min(rtk["wall"])}}
    names = {"leonav_in_process": "leonav spp (a) in-process",
             "leonav_process_lean": "leonav spp (b) python -m ...commands.spp",
             "leonav_cli": "leonav spp (c) leonav command line",
             "leonav_cli_compressed": "leonav spp (d) as (c), .YYd.gz/.gz inputs",
             "leonav_cli_baseline": "leonav spp (c) of --baseline TREE"}
    for k, (name, title) in enumerate((n, t) for n, t in names.items() if n in res):
        ref = [rtk["cpu"][r * per + k] for r in range(len(res[name]["cpu"]))]
        ref_w = [rtk["wall"][r * per + k] for r in range(len(res[name]["wall"]))]
        ratio = statistics.median(c / r for c, r in zip(res[name]["cpu"], ref))
        ratio_w = statistics.median(c / r for c, r in zip(res[name]["wall"], ref_w))
        cpu, wall = min(res[name]["cpu"]), min(res[name]["wall"])
        print(f"  {title:44s} {cpu:7.3f} {wall:7.3f}  {ratio:8.2f}x {cpu / min(rtk['cpu']):10.2f}x {ratio_w:9.2f}x")
        summary[name] = {"cpu_s": cpu, "wall_s": wall, "cpu_ratio_median": ratio, "wall_ratio_median": ratio_w}
    print(f"  {'floor: python -c import numpy':44s} {floor[0]:7.3f} {floor[1]:7.3f}  {'':9s} "
          f"{floor[0] / min(rtk['cpu']):10.2f}x")
    summary["python_numpy_floor"] = {"cpu_s": floor[0], "wall_s": floor[1]}
    return summary


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default=None)
    ap.add_argument("--baseline", type=Path, default=None, metavar="TREE",
                    help="another leonav checkout (e.g. the code before a change): its (c) is timed in the same "
                         "pairs and its .pos files compared with this tree's")
    args = ap.parse_args()
    if shutil.which("rnx2rtkp") is None or not DATA.is_dir():
        print("needs rnx2rtkp on PATH and ../shared/data/gnss_rinex", file=sys.stderr)
        return 2
    os.chdir(REPO)
    load0 = os.getloadavg()
    print(f"load average before: {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f} ({os.cpu_count()} CPUs)")
    results = {"load_before": load0}
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        CHILD_ENV["PYTHONPYCACHEPREFIX"] = str(tmp / "pycache")
        try:
            compressed = compressed_copies(tmp)
        except ImportError:
            compressed = None
            print("hatanaka not installed: no compressed-input line")
        floor_argv = [sys.executable, "-c", "import numpy"]
        run_process(floor_argv)
        floors = [run_process(floor_argv) for _ in range(max(3, args.repeats))]
        floor = (min(c for c, _ in floors), min(w for _, w in floors))
        for atmosphere in (False, True):
            label = "Klobuchar + Saastamoinen" if atmosphere else "no atmosphere terms (rnx2rtkp -p 0 defaults)"
            res = paired(args.repeats, tmp, atmosphere, compressed, args.baseline)
            results[label] = report(label, res, floor, args.repeats)
            if args.baseline:
                same = all((tmp / "out_cli" / f"{st}0920_05o{ext}").read_bytes() ==
                           (tmp / "out_cli_baseline" / f"{st}0920_05o{ext}").read_bytes()
                           for st in STATIONS for ext in (".pos", ".csv"))
                print(f"  .pos and .csv of (c) byte-identical to the baseline's: {same}")
                results[label]["same_as_baseline"] = same
    load1 = os.getloadavg()
    results["load_after"] = load1
    print(f"\nload average after: {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
    print("goals (quiet machine): in-process <= 2x rnx2rtkp's CPU, as a command <= 6x")
    if args.out:
        Path(args.out).mkdir(parents=True, exist_ok=True)
        (Path(args.out) / "bench_spp.json").write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
