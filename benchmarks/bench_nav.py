"""`leonav nav` figures: latency, CPU, beacon streaming throughput and memory.

    python benchmarks/bench_nav.py                      # all three parts (~3 minutes on 2 cores)
    python benchmarks/bench_nav.py --part latency --seconds 60
    python benchmarks/bench_nav.py --part beacons --beacon-seconds 600

1. latency / CPU: a synthetic session with a 100 Hz IMU (WitMotion packets at 115200 baud) and
   10 Hz GNSS (NMEA RMC+GGA+GST at 38400 baud) is fed through two pty pairs at its recorded pace
   (this process plays the devices); `leonav nav --gnss PTY --imu PTY` runs as a child process
   with its default outputs (NMEA TCP server on a free loopback port, solutions.jsonl, recording).
   Latency: from the moment the reader thread has the IMU packet that completes a sample (its last
   byte read and decoded) to the updated solution (filter stepped, and on the 10 Hz output grid the
   solution sent) - nav.json `latency_ms`. CPU: the child's user+system time over wall time
   between 5 s after the start and the end (steady state), in % of one core.
2. beacon throughput / memory: `nav.beacon_stream.BeaconStream` (the live pipeline) on a 2.4 MS/s
   synthetic Starlink capture (5 satellites of the built-in constellation, cu8 as the RTL-SDR gives
   it), pushed in 0.1 s pieces; time of the pushes only (the synthesis is not timed) against the
   data's duration, and the process's resident memory every 10 s of data.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import socket
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
TICK = os.sysconf("SC_CLK_TCK")


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK      # utime + stime


def _rss_mb() -> float:
    return int(Path("/proc/self/statm").read_text().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def latency_and_cpu(seconds: float, work: Path) -> dict:
    from leonav_runtime.nav import sources
    from leonav_runtime.simulation.session_synth import SynthSessionConfig, write_synthetic_session

    folder = work / "s100"
    print(f"synthesizing a {seconds:g} s session: IMU 100 Hz at 115200 baud, GNSS 10 Hz at 38400 baud ...", flush=True)
    write_synthetic_session(folder, SynthSessionConfig(seconds=seconds, imu_rate_hz=100.0, gnss_rate_hz=10.0,
                                                       imu_baud=115200, sdr=False), overwrite=True)
    t0 = sources.session_start_mono(folder)
    ptys = {n: sources.PacedPty(sources.chunk_events(folder, n, t0)) for n in ("gnss", "imu")}
    out = work / "nav100"
    cmd = [sys.executable, "-c", "import sys; from leonav_runtime.cli import main; sys.exit(main(sys.argv[1:]))",
           "nav", "--gnss", ptys["gnss"].path, "--imu", ptys["imu"].path, "--gnss-baud", "38400",
           "--imu-baud", "115200", "--seconds", f"{seconds + 1.5:g}", "--nmea-port", str(_free_port()),
           "--quiet", "--out", str(out)]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.monotonic() + 30
        while not (out / "session" / "session.json").exists() and time.monotonic() < deadline:
            time.sleep(0.02)                         # the ports are open once the recorder has started
        for p in ptys.values():
            p.start()
        t_start = time.monotonic()
        time.sleep(5.0)
        c1, w1 = _cpu_s(proc.pid), time.monotonic()
        while time.monotonic() < t_start + seconds - 0.5 and proc.poll() is None:
            time.sleep(0.1)
        c2, w2 = _cpu_s(proc.pid), time.monotonic()
        text, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
        for p in ptys.values():
            p.close()
    nav = json.loads((out / "nav.json").read_text())
    return {"exit_code": proc.returncode, "latency_ms": nav["latency_ms"], "cpu_percent": 100 * (c2 - c1) / (w2 - w1),
            "imu_samples": nav["road"].get("imu_samples"), "fixes": nav["road"].get("fix_released"),
            "solutions": nav["outputs"]["solutions"], "imu_timing": nav["imu_timing"], "output": text.strip()}


def beacon_throughput(seconds: float, carrier_phase: bool = False) -> dict:
    from leonav_runtime.beacons import capture_io, synth
    from leonav_runtime.beacons.predict import Site
    from leonav_runtime.gen.constants import STARLINK_BEACON_HZ
    from leonav_runtime.nav.beacon_feed import cu8_to_complex
    from leonav_runtime.nav.beacon_stream import BeaconStream
    from leonav_runtime.simulation.session_synth import PAPER_EPOCH, ROCHESTER, builtin_starlink

    warnings.simplefilter("ignore")
    fs = 2.4e6
    site = Site(math.radians(ROCHESTER[0]), math.radians(ROCHESTER[1]), ROCHESTER[2])
    elements = builtin_starlink(PAPER_EPOCH)
    cfg = synth.SynthConfig(duration_s=seconds, sample_rate_hz=fs, n_satellites=5, cn0_dbhz=40.0, seed=1)
    truth = synth.build_truth(elements, site, PAPER_EPOCH, cfg)
    rf_center = cfg.center_freq_hz + cfg.lnb_lo_hz
    bs = BeaconStream(fs, rf_center, STARLINK_BEACON_HZ, elements, carrier_phase=carrier_phase)
    bs.set_site(site, PAPER_EPOCH)
    piece = int(0.1 * fs)
    busy = cpu = 0.0
    done = 0
    rss, next_mark, emitted, phase = [], 10.0, [], 0
    print(f"beacon stream{' with carrier tracking' if carrier_phase else ''}: {seconds:g} s of 2.4 MS/s cu8, "
          "5 satellites (synthesis not timed) ...", flush=True)
    for x in synth.iter_synthetic_iq(truth, cfg):
        raw = capture_io.quantize_cu8(x, 1.0).tobytes()
        t0, c0 = time.perf_counter(), time.process_time()
        z = cu8_to_complex(raw)
        for k in range(0, z.size, piece):
            bs.push(z[k:k + piece])
            emitted += bs.take()
            phase += len(bs.take_phase())
        busy += time.perf_counter() - t0
        cpu += time.process_time() - c0
        done += z.size
        if done / fs >= next_mark:
            rss.append((round(done / fs), round(_rss_mb(), 1)))
            next_mark += 10.0
    lags = [e.data_lag_s for e in emitted]
    late = rss[len(rss) // 2:]
    slope = np.polyfit([r[0] for r in late], [r[1] for r in late], 1)[0] if len(late) > 2 else float("nan")
    return {"data_s": done / fs, "busy_s": busy, "cpu_s": cpu, "x_real_time": done / fs / busy,
            "x_real_time_cpu": done / fs / cpu, "measurements": len(emitted),
            "satellites": len({e.norad_id for e in emitted}), "max_lag_s": max(lags) if lags else None,
            "phase_differences": phase, "tones_tracked": len(bs.tones),
            "counts": bs.counts, "rss_mb": rss, "rss_slope_mb_per_min_second_half": 60 * slope}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--part", choices=("all", "latency", "beacons"), default="all")
    ap.add_argument("--seconds", type=float, default=40.0, help="latency/CPU run length (s)")
    ap.add_argument("--beacon-seconds", type=float, default=180.0, help="beacon stream length (s of data)")
    ap.add_argument("--carrier-phase", action="store_true",
                    help="beacons part: also the stream with carrier tracking of every identified tone, side by side")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        if args.part in ("all", "latency"):
            r = latency_and_cpu(args.seconds, Path(tmp))
            lat = r["latency_ms"]
            print(f"\nlive path, IMU 100 Hz + GNSS 10 Hz over ptys, {args.seconds:g} s (exit {r['exit_code']}):")
            print(f"  IMU packet -> updated solution latency: p50 {lat['p50']:.2f} ms, p99 {lat['p99']:.2f} ms "
                  f"({lat['samples']} samples)   goal p99 <= 20 ms: {lat['p99'] <= 20}")
            print(f"  CPU: {r['cpu_percent']:.1f} % of one core (steady state)   goal <= 20 %: {r['cpu_percent'] <= 20}")
            print(f"  {r['imu_samples']} IMU samples, {r['fixes']} fixes applied, {r['solutions']} solutions sent; "
                  f"IMU timing {r['imu_timing']}")
        if args.part in ("all", "beacons"):
            b = beacon_throughput(args.beacon_seconds)
            print(f"\nbeacon streaming, 2.4 MS/s: {b['data_s']:.0f} s of data in {b['busy_s']:.1f} s wall = "
                  f"{b['x_real_time']:.1f}x real time   goal >= 5x: {b['x_real_time'] >= 5}")
            print(f"  CPU time {b['cpu_s']:.1f} s (FFT on 2 threads) = {b['x_real_time_cpu']:.1f}x real time per "
                  f"CPU-second; load average at the end {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
            print(f"  {b['measurements']} Doppler-rate measurements from {b['satellites']} satellites, max lag "
                  f"{b['max_lag_s']:.2f} s after the newest sample; {b['counts']}")
            print(f"  resident memory (s of data, MB): {b['rss_mb']}")
            print(f"  slope over the second half: {b['rss_slope_mb_per_min_second_half']:+.2f} MB per minute of data")
            if args.carrier_phase:
                c = beacon_throughput(args.beacon_seconds, carrier_phase=True)
                print(f"\nbeacon streaming with carrier tracking: {c['x_real_time']:.1f}x real time wall, "
                      f"{c['x_real_time_cpu']:.1f}x per CPU-second; CPU {c['cpu_s']:.1f} s = {c['cpu_s'] / b['cpu_s']:.2f}x "
                      f"the stream without; {c['tones_tracked']} tones tracked, {c['phase_differences']} phase "
                      f"differences, {c['measurements']} Doppler-rate measurements")
                print(f"  resident memory (s of data, MB): {c['rss_mb']}; slope over the second half "
                      f"{c['rss_slope_mb_per_min_second_half']:+.2f} MB per minute of data")


if __name__ == "__main__":
    main()
