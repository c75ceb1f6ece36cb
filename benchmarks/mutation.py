"""Mutation testing: does the test suite notice a realistic bug?

Each mutant in `benchmarks/mutants.py` is one small edit of one source file (a flipped
sign, a swapped field, a wrong scale, a dropped check). The script copies the project's
tracked files into a temporary folder once, then for every mutant: applies the edit to
the copy (never to the working files), regenerates the C when the edit is in `models/`
(`python -m leonav.codegen` into the copy), runs that module's tests with pytest, and puts the
original file back. A mutant is *killed* when pytest fails (or times out), *survives*
when it passes. Mutants marked equivalent in the catalogue (no behaviour a user could
see, reason given there) are run but not counted in the score.

    python benchmarks/mutation.py                     # every module
    python benchmarks/mutation.py --module gnss tle   # some modules
    python benchmarks/mutation.py --list              # the catalogue, no runs
    python benchmarks/mutation.py --tests-rev REV     # tests/ as in git revision REV
                                                      # ("before" scores of older tests)
    python benchmarks/mutation.py --only gnss-03      # one mutant (by id)
    python benchmarks/mutation.py --only simulate-01 --show   # ... and the failure it causes

Not part of the normal test run. It takes a few minutes per module on two cores;
run it under `nice`. Real data: `LEONAV_SHARED_DATA` (default ../shared/data beside the
working tree) is passed to the tests, and a module whose unmutated tests skip or fail is
reported as such instead of scored.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from mutants import MODULES, MUTANTS, Mutant  # noqa: E402


def tracked_files(root: Path) -> list[str]:
    out = subprocess.run(["git", "ls-files", "-z"], cwd=root, capture_output=True, check=True)
    return [p for p in out.stdout.decode().split("\0") if p]


def make_copy(root: Path, dest: Path, tests_rev: str | None) -> None:
    """Copy the tracked files (as they are in the working tree, uncommitted edits included)."""
    for rel in tracked_files(root):
        src = root / rel
        if not src.is_file():
            continue
        target = dest / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, target)
    # new test files not yet committed count too
    untracked = subprocess.run(["git", "ls-files", "-z", "--others", "--exclude-standard", "tests", "benchmarks"],
                               cwd=root, capture_output=True, check=True).stdout.decode().split("\0")
    for rel in filter(None, untracked):
        target = dest / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(root / rel, target)
    # models/, codegen/, hardware/ install as leonav.models, ... (setup.py): links inside the copy's
    # leonav/ make those names import the copy (else the editable install maps them to the working tree)
    for folder in ("models", "codegen", "hardware"):
        link = dest / "leonav" / folder
        if (dest / folder).is_dir() and not link.exists():
            link.symlink_to(Path("..") / folder, target_is_directory=True)
    if tests_rev:
        shutil.rmtree(dest / "tests")
        archive = subprocess.run(["git", "archive", tests_rev, "tests"], cwd=root, capture_output=True, check=True)
        subprocess.run(["tar", "-x", "-C", str(dest)], input=archive.stdout, check=True)


def apply(text: str, m: Mutant) -> str:
    """The mutated text; every (find, replace) pair must match exactly once."""
    for find, repl in m.edits:
        n = text.count(find)
        if n != 1:
            raise ValueError(f"mutant {m.id}: {find!r} occurs {n} times in {m.path} (need exactly 1)")
        text = text.replace(find, repl)
    try:  # a mutant must be a program, not a syntax error that any import would catch
        compile(text, m.path, "exec")
    except SyntaxError as exc:
        raise ValueError(f"mutant {m.id}: the edit makes {m.path} invalid Python ({exc.msg}, line {exc.lineno})")
    return text


def run_tests(copy: Path, tests: list[str], env: dict, timeout_s: float) -> tuple[str, float, str]:
    """('pass' | 'fail' | 'timeout' | 'error', seconds, last lines of output)."""
    present = [t for t in tests if (copy / t.split("::")[0]).exists()]
    if not present:
        return "error", 0.0, "no test file of this module exists here"
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "-o", "addopts=",
           "--no-header", "-rs", *present]
    start = time.perf_counter()
    try:
        proc = subprocess.run(cmd, cwd=copy, env=env, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return "timeout", time.perf_counter() - start, ""
    elapsed = time.perf_counter() - start
    tail = "\n".join((proc.stdout + proc.stderr).strip().splitlines()[-6:])
    if proc.returncode == 0:
        return ("skipped" if " skipped" in tail else "pass"), elapsed, tail
    if proc.returncode == 1:
        return "fail", elapsed, tail
    return "error", elapsed, tail


def regenerate(copy: Path, env: dict) -> tuple[bool, str]:
    proc = subprocess.run([sys.executable, "-m", "leonav.codegen"], cwd=copy, env=env, capture_output=True, text=True)
    return proc.returncode == 0, (proc.stdout + proc.stderr).strip()[-400:]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--module", nargs="*", default=None, help=f"modules to run (default all: {', '.join(MODULES)})")
    ap.add_argument("--only", nargs="*", default=None, help="mutant ids to run")
    ap.add_argument("--tests-rev", default=None, help="take tests/ from this git revision")
    ap.add_argument("--list", action="store_true", help="print the catalogue and exit")
    ap.add_argument("--json", default=None, help="write the per-mutant results here")
    ap.add_argument("--show", action="store_true", help="print the end of pytest's output for every mutant")
    args = ap.parse_args(argv)

    modules = args.module or list(MODULES)
    mutants = [m for m in MUTANTS if m.module in modules and (not args.only or m.id in args.only)]
    if args.list:
        bad = 0
        for m in mutants:
            eq = f"  [equivalent: {m.equivalent}]" if m.equivalent else ""
            print(f"{m.id:12s} {m.path}: {m.what}{eq}")
            try:  # each edit must still match the current source exactly once
                apply((ROOT / m.path).read_text(), m)
            except ValueError as exc:
                print(f"  DOES NOT APPLY: {exc}")
                bad += 1
        return 1 if bad else 0

    env = dict(os.environ)
    data = Path(env.get("LEONAV_SHARED_DATA", ROOT.parent / "shared" / "data"))
    env["LEONAV_SHARED_DATA"] = str(data)
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    print(f"real data: {data} ({'found' if data.is_dir() else 'MISSING: data tests will skip'})", flush=True)

    results = []
    with tempfile.TemporaryDirectory(prefix="leonav-mutation-") as tmp:
        copy = Path(tmp) / "leonav"
        make_copy(ROOT, copy, args.tests_rev)
        check = subprocess.run([sys.executable, "-c", "import leonav.hardware, leonav_runtime, leonav.models as m; "
                                "print(leonav_runtime.__file__, leonav.hardware.__file__, m.__file__)"],
                               cwd=copy, env=env, capture_output=True, text=True)
        if not check.stdout.split() or not all(f.startswith(str(copy)) for f in check.stdout.split()):
            print(f"the copy does not import its own modules ({check.stdout.strip()}): stop", file=sys.stderr)
            return 2
        for module in modules:
            spec = MODULES[module]
            todo = [m for m in mutants if m.module == module]
            if not todo:
                continue
            status, base_s, tail = run_tests(copy, spec["tests"], env, timeout_s=1800)
            print(f"\n== {module}: {len(todo)} mutants; unmutated tests: {status} in {base_s:.1f} s", flush=True)
            if status != "pass":
                print(tail)
                for m in todo:
                    results.append(dict(id=m.id, module=module, outcome="not run (" + status + ")",
                                        equivalent=bool(m.equivalent)))
                continue
            timeout = 3 * base_s + 60
            for m in todo:
                path = copy / m.path
                original = path.read_text()
                try:
                    mutated = apply(original, m)
                except ValueError as exc:   # the source moved on while the run went: say so, go on
                    print(f"  {m.id:12s} DOES NOT APPLY: {exc}", flush=True)
                    results.append(dict(id=m.id, module=module, what=m.what, outcome="does not apply", killed=False,
                                        equivalent=bool(m.equivalent), seconds=0.0))
                    continue
                try:
                    path.write_text(mutated)
                    outcome, secs, tail = "", 0.0, ""
                    if m.path.startswith("models/"):
                        ok, msg = regenerate(copy, env)
                        if not ok:
                            outcome, tail = "fail", "codegen failed: " + msg
                    if not outcome:
                        outcome, secs, tail = run_tests(copy, spec["tests"], env, timeout)
                finally:
                    path.write_text(original)
                    if m.path.startswith("models/"):
                        regenerate(copy, env)
                killed = outcome in ("fail", "timeout")
                mark = "killed" if killed else ("SURVIVED" if outcome == "pass" else outcome.upper())
                eq = "  (equivalent)" if m.equivalent else ""
                print(f"  {m.id:12s} {mark:9s} {secs:6.1f} s  {m.what}{eq}", flush=True)
                if outcome == "error" or args.show:
                    print("    " + tail.replace("\n", "\n    "))
                results.append(dict(id=m.id, module=module, what=m.what, outcome=outcome, killed=killed,
                                    equivalent=bool(m.equivalent), seconds=round(secs, 1)))

    print("\nmodule     mutants  equivalent  killed  score   survivors")
    for module in modules:
        rs = [r for r in results if r["module"] == module]
        if not rs:
            continue
        counted = [r for r in rs if not r["equivalent"]]
        killed = sum(r.get("killed", False) for r in counted)
        surv = [r["id"] for r in counted if not r.get("killed", False)]
        score = 100.0 * killed / len(counted) if counted else float("nan")
        print(f"{module:10s} {len(rs):7d}  {len(rs) - len(counted):10d}  {killed:6d}  {score:5.0f} %  "
              f"{' '.join(surv) or '-'}")
    eq_alive = [r for r in results if r["equivalent"] and not r.get("killed", False)]
    if eq_alive:
        print("\nequivalent mutants (not scored):")
        for r in eq_alive:
            m = next(x for x in MUTANTS if x.id == r["id"])
            print(f"  {m.id:12s} {m.what}: {m.equivalent}")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
