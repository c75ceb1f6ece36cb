"""`leonav nav` latency with and without a TCP client storm, side by side in one run.

    python benchmarks/bench_nav_load.py                 # 30 s session, one quiet and one stormed run
    python benchmarks/bench_nav_load.py --seconds 60 --repeat 2

A synthetic session (IMU 100 Hz at 115200 baud, GNSS 10 Hz) is played back at its recorded pace
through pty devices by `leonav nav --from S --realtime --nmea-port auto` in a child process under
`ulimit -n 256` (tests/nav_storm.py). The stormed run gets 1,000 TCP clients opened and closed in
waves of 100 spread over the session, plus 10 clients that never read, held all along; the quiet
run gets none. Runs alternate quiet/stormed. Figures per run: the latency from an IMU packet's
arrival to its updated solution (nav.json latency_ms, p50/p99), the child's CPU time (user+system
from the kernel's accounting of the waited child, a CPU clock), its wall time (named as such), and
the server's client counts; then the stormed/quiet ratios. The load average is printed before and
after: the machine is shared, and latency percentiles move with its load.
"""
from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _children_cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def one_run(session: Path, out: Path, seconds: float, stormed: bool) -> dict:
    from tests.nav_storm import NavChild, dead_clients, storm

    c0, w0 = _children_cpu_s(), time.monotonic()
    child = NavChild(session, out, nofile=256)
    port = child.wait_serving()
    held, seen = [], {}
    try:
        if stormed:
            held = dead_clients(port, 10)
            seen = storm(port, total=1000, wave=100, pause_s=max(0.05, (seconds - 3.0) / 10))
        code, nav, _, text = child.wait(timeout_s=seconds + 60)
    finally:
        for s in held:
            s.close()
    if code != 0 or not nav:
        raise SystemExit(f"nav exited {code}:\n{text}")
    return {"latency_ms": nav["latency_ms"], "cpu_s": _children_cpu_s() - c0, "wall_s": time.monotonic() - w0,
            "tcp": nav["outputs"].get("tcp", {}), "seen": seen, "rows": nav["trajectory_rows"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=30.0, help="session length (s)")
    ap.add_argument("--repeat", type=int, default=1, help="quiet/stormed pairs")
    args = ap.parse_args()
    from leonav_runtime.simulation.session_synth import SynthSessionConfig, write_synthetic_session

    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())} on {os.cpu_count()} cores")
    runs: dict[str, list[dict]] = {"quiet": [], "stormed": []}
    with tempfile.TemporaryDirectory() as tmp:
        session = Path(tmp) / "s"
        write_synthetic_session(session, SynthSessionConfig(seconds=args.seconds, seed=4, sdr=False,
                                                            imu_rate_hz=100.0, imu_baud=115200))
        for i in range(args.repeat):
            for kind in ("quiet", "stormed"):
                r = one_run(session, Path(tmp) / f"{kind}{i}", args.seconds, kind == "stormed")
                runs[kind].append(r)
                lat, tcp = r["latency_ms"], r["tcp"]
                print(f"{kind:8s} run {i + 1}: latency p50 {lat['p50']:6.2f} ms  p99 {lat['p99']:6.2f} ms "
                      f"({lat['samples']} samples); CPU {r['cpu_s']:.2f} s; wall {r['wall_s']:.1f} s; "
                      f"clients accepted {tcp.get('clients_accepted', 0)}, refused {tcp.get('clients_refused_limit', 0)}"
                      f", accept errors {tcp.get('accept_errors', 0)}; {r['rows']} trajectory rows", flush=True)
    print(f"load average after:  {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    q, s = runs["quiet"], runs["stormed"]

    def mean(rs: list[dict], f) -> float:
        return sum(f(r) for r in rs) / len(rs)

    for name, f in (("p50 latency", lambda r: r["latency_ms"]["p50"]), ("p99 latency", lambda r: r["latency_ms"]["p99"]),
                    ("CPU time", lambda r: r["cpu_s"])):
        a, b = mean(q, f), mean(s, f)
        unit = "s" if name == "CPU time" else "ms"
        print(f"{name:12s} quiet {a:7.2f} {unit}   stormed {b:7.2f} {unit}   stormed/quiet x{b / a:.2f}")
    worst = max(r["latency_ms"]["p99"] for r in s)
    print(f"stormed p99 worst {worst:.2f} ms   goal < 50 ms: {worst < 50}")


if __name__ == "__main__":
    main()
