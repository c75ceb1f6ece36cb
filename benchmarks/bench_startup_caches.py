"""Start-up cost of locating the compiled library and reading the EOP table (issue 25).

Each figure is the CPU time (time.process_time) of `compiled.load()` or `eop.default_table()` in a
fresh interpreter, warm caches, best of N, with the memo/cache on and off measured alternately
(`LEONAV_KEY_MEMO=off`: every source hashed; `LEONAV_EOP_CACHE=off`: every row parsed).

    python benchmarks/bench_startup_caches.py [--repeats 5]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys

SNIPPETS = {
    "compiled.load()": "from leonav_runtime.core import compiled\nt = time.process_time()\ncompiled.load()",
    "eop.default_table()": "from leonav_runtime.orbits import eop\nt = time.process_time()\neop.default_table()",
}
SWITCH = {"compiled.load()": "LEONAV_KEY_MEMO", "eop.default_table()": "LEONAV_EOP_CACHE"}


def one(snippet: str, env_name: str, on: bool) -> float:
    env = dict(os.environ)
    env.pop(env_name, None)
    if not on:
        env[env_name] = "off"
    code = "import time\n" + snippet + "\nprint(time.process_time() - t)"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return float(out.stdout.split()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    with open("/proc/loadavg") as fh:
        load_before = fh.read().split()[0]
    for name, snippet in SNIPPETS.items():
        one(snippet, SWITCH[name], True)   # warm the caches
        on, off = [], []
        for _ in range(args.repeats):
            on.append(one(snippet, SWITCH[name], True))
            off.append(one(snippet, SWITCH[name], False))
        print(f"{name:22s} cached {min(on) * 1e3:6.1f} ms (median {sorted(on)[len(on) // 2] * 1e3:5.1f})   "
              f"uncached {min(off) * 1e3:6.1f} ms (median {sorted(off)[len(off) // 2] * 1e3:5.1f})   "
              f"ratio {min(off) / min(on):4.1f}x")
    with open("/proc/loadavg") as fh:
        print(f"load average {load_before} -> {fh.read().split()[0]}")


if __name__ == "__main__":
    main()
