"""Beacon pipeline benchmark: processing time and peak memory of a full-rate capture, and
association accuracy versus C/N0.

    python benchmarks/bench_beacons.py                 # 20 s at 2.4 MS/s (RTL-SDR cu8, 96 MB)
    python benchmarks/bench_beacons.py --snr-table     # + accuracy vs C/N0 (reduced rate, 10 trials each)
    python benchmarks/bench_beacons.py --lo-table      # + joint LO offset/drift error and combs (20 trials)

The capture is synthesized first (not timed) from the real Starlink element sets in
../shared/data/tle/starlink_2026-02-23.txt at the paper's Rochester site; processing is then
timed in a fresh child process so its peak RSS (resource.getrusage) is the pipeline's own.
"""
from __future__ import annotations

import argparse
import datetime as dt
import json
import logging
import resource
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
TLE = ROOT.parent / "shared" / "data" / "tle" / "starlink_2026-02-23.txt"
START = dt.datetime(2026, 2, 23, 6, 0, tzinfo=dt.timezone.utc)
SITE_DEG = (43.0848638, -77.6786127, 170.0)
TONES = 1


def _quiet():
    warnings.simplefilter("ignore")
    logging.disable(logging.WARNING)


def child_process(capture: str) -> None:
    """Process one capture and print JSON with time and peak RSS (run in a fresh interpreter)."""
    _quiet()
    from leonav_runtime.beacons import capture_io, pipeline
    from leonav_runtime.beacons.predict import Site
    from leonav_runtime.orbits import load_elements

    elements = load_elements(TLE)
    site = Site.from_degrees(*SITE_DEG)
    t0 = time.perf_counter()
    info = capture_io.open_capture(capture)
    res = pipeline.process_capture(info, elements, site)
    t1 = time.perf_counter()
    s = pipeline.summary(res)
    print(json.dumps({"seconds": t1 - t0, "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                      "counts": s["counts"], "residual": s["rate_residual_abs_hz_s"],
                      "lo": {k: s["lo"][k] for k in ("offset_hz", "drift_hz_s", "drift_removed")},
                      "duration_s": info.duration_s, "bytes": info.path.stat().st_size}))


def full_rate() -> None:
    _quiet()
    from leonav_runtime.beacons import synth
    from leonav_runtime.beacons.predict import Site
    from leonav_runtime.orbits import load_elements

    elements = load_elements(TLE)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.cu8"
        cfg = synth.SynthConfig(duration_s=20.0, sample_rate_hz=2.4e6, cn0_dbhz=38.0, n_satellites=6, seed=11,
                                tones_per_satellite=TONES, full_comb_in_band=False)
        t0 = time.perf_counter()
        _, truth = synth.write_synthetic_capture(path, elements, Site.from_degrees(*SITE_DEG), START, cfg)
        t_synth = time.perf_counter() - t0
        out = subprocess.run([sys.executable, __file__, "--child", str(path)], capture_output=True, text=True, check=True)
        r = json.loads(out.stdout.strip().splitlines()[-1])
    print(f"full-rate capture (RTL-SDR cu8, 6 satellites x {TONES} tones at 38 dB-Hz, LO drift 0.3 Hz/s)")
    print(f"  capture: {r['duration_s']:.1f} s at 2.4 MS/s, {r['bytes'] / 1e6:.0f} MB (synthesized in {t_synth:.1f} s)")
    print(f"  processing time {r['seconds']:.2f} s  vs capture duration {r['duration_s']:.1f} s  "
          f"(ratio {r['seconds'] / r['duration_s']:.2f}x real time; budget 20 s)")
    print(f"  peak RSS {r['peak_rss_mb']:.0f} MB (budget 1024 MB; capture file {r['bytes'] / 1e6:.0f} MB)")
    print(f"  ridges {r['counts']}, |delta alpha| {r['residual']}")
    print(f"  truth: {list(map(int, truth.norad_ids))}; LO offset {-truth.lo_err_hz[np.searchsorted(truth.t_grid_s, 0)]:.1f} Hz "
          f"(estimated {r['lo']['offset_hz']:.1f}), drift -0.3 Hz/s (estimated {r['lo']['drift_hz_s']:.3f}, "
          f"removed: {r['lo']['drift_removed']})")


def snr_table(trials: int = 10) -> None:
    _quiet()
    from leonav_runtime.beacons import pipeline, synth
    from leonav_runtime.beacons.predict import Site
    from leonav_runtime.orbits import load_elements

    elements = load_elements(TLE)
    site = Site.from_degrees(*SITE_DEG)
    fs, dur = 400e3, 10.0
    print(f"\naccuracy vs C/N0 ({trials} trials each, 5 tones, {dur:g} s at {fs / 1e3:g} kS/s; "
          f"per-bin SNR = C/N0 - 10log10({fs / 4096:.1f} Hz) - 1.8 dB Hann)")
    print(" C/N0 dB-Hz | per-bin dB | tones found | right sat | wrong | ambiguous | unassoc. | median |da| | mean |da| | max |da|")
    with tempfile.TemporaryDirectory() as tmp:
        for cn0 in (26.0, 28.0, 30.0, 33.0, 36.0, 40.0):
            found = right = wrong = amb = una = 0
            res_all = []
            for seed in range(trials):
                cfg = synth.SynthConfig(duration_s=dur, sample_rate_hz=fs, cn0_dbhz=cn0, seed=100 + seed,
                                        lo_offset_hz=float(np.random.default_rng(seed).uniform(-30e3, 30e3)))
                start = START + dt.timedelta(minutes=41 * seed)
                info, truth = synth.write_synthetic_capture(Path(tmp) / "s.cu8", elements, site, start, cfg)
                res = pipeline.process_capture(info, elements, site, pipeline.PipelineConfig(band_hz=fs))
                for a in res.associations:
                    ok = a.norad_id in truth.norad_ids
                    right += a.status == "associated" and ok
                    wrong += a.status == "associated" and not ok
                    amb += a.status == "ambiguous"
                    una += a.status == "unassociated"
                    if a.status == "associated":
                        res_all.append(np.abs(a.rate_residual_hz_s))
                found += len({a.norad_id for a in res.associations if a.norad_id in truth.norad_ids})
            r = np.concatenate(res_all) if res_all else np.array([np.nan])
            n = 5 * trials
            print(f" {cn0:10.0f} | {cn0 - 10 * np.log10(fs / 4096) - 1.76:10.1f} | {found:5d}/{n:<5d} | {right:9d} | "
                  f"{wrong:5d} | {amb:9d} | {una:8d} | {np.median(r):12.2f} | {np.mean(r):10.2f} | {np.max(r):8.2f}")


def lo_table(trials: int = 20) -> None:
    """Joint LO fit: offset/drift error, rate bias before/after, association accuracy, 1 and 5 tones."""
    _quiet()
    from leonav_runtime.beacons import lo_fit, pipeline, synth
    from leonav_runtime.beacons.predict import Site
    from leonav_runtime.orbits import load_elements

    elements = load_elements(TLE)
    site = Site.from_degrees(*SITE_DEG)
    fs, dur = 400e3, 10.0
    print(f"\njoint LO offset/drift ({trials} trials each, {dur:g} s at {fs / 1e3:g} kS/s, 35 dB-Hz, drift 1 Hz/s "
          f"+ random walk 0.05 Hz^2/s, offset uniform +/-30 kHz)")
    print(" tones/sat | right/ridges | combs/sats | |offset err| med/max Hz | |drift err| med/max Hz/s | "
          "rate bias raw -> sent Hz/s | median |da| sent")
    with tempfile.TemporaryDirectory() as tmp:
        for tones, nsat in ((1, 5), (5, 3)):
            right = ridges = combs = sats = 0
            off_err, drift_err, raw_b, sent_b, sent_abs = [], [], [], [], []
            for seed in range(trials):
                cfg = synth.SynthConfig(duration_s=dur, sample_rate_hz=fs, cn0_dbhz=35.0, seed=200 + seed,
                                        lo_drift_hz_s=1.0, n_satellites=nsat, tones_per_satellite=tones,
                                        full_comb_in_band=False,
                                        lo_offset_hz=float(np.random.default_rng(seed).uniform(-30e3, 30e3)))
                info, truth = synth.write_synthetic_capture(Path(tmp) / "s.cu8", elements, site,
                                                            START + dt.timedelta(minutes=43 * seed), cfg)
                res = pipeline.process_capture(info, elements, site, pipeline.PipelineConfig(band_hz=fs))
                ridges += len(res.associations)
                right += sum(a.status == "associated" and a.norad_id in truth.norad_ids for a in res.associations)
                combs += len(res.combs)
                sats += nsat
                inside = (truth.t_grid_s >= 0) & (truth.t_grid_s <= dur)
                slope, icpt = np.polyfit(truth.t_grid_s[inside], -truth.lo_err_hz[inside], 1)
                off_err.append(abs(lo_fit.wrap(res.lo.offset_hz - icpt, 43949.5)))
                drift_err.append(abs(res.lo.drift_hz_s - slope))
                for m0, m, a in zip(res.ridge_measurements, res.measurements, res.associations):
                    if a.status != "associated" or a.norad_id not in truth.norad_ids:
                        continue
                    row = list(truth.norad_ids).index(a.norad_id)
                    raw_b.append(m0.rate_hz_s - np.interp(m0.t_s, truth.t_grid_s, truth.rate_hz_s[row]))
                    if m.t_s.size:
                        e = m.rate_hz_s - np.interp(m.t_s, truth.t_grid_s, truth.rate_hz_s[row])
                        sent_b.append(e)
                        sent_abs.append(np.abs(a.rate_residual_hz_s))
            rb, sb = np.concatenate(raw_b), np.concatenate(sent_b)
            print(f" {tones:9d} | {right:5d}/{ridges:<6d} | {combs:4d}/{sats:<5d} | "
                  f"{np.median(off_err):10.2f} / {np.max(off_err):8.2f} | {np.median(drift_err):11.3f} / "
                  f"{np.max(drift_err):6.3f} | {np.mean(rb):+10.3f} -> {np.mean(sb):+6.3f} | "
                  f"{np.median(np.concatenate(sent_abs)):.2f}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--child", metavar="CAPTURE", help=argparse.SUPPRESS)
    ap.add_argument("--snr-table", action="store_true", help="also print accuracy versus C/N0")
    ap.add_argument("--lo-table", action="store_true", help="also print the joint LO fit table")
    ap.add_argument("--tones", type=int, default=1, help="tones per satellite in the full-rate capture")
    ap.add_argument("--trials", type=int, default=10)
    a = ap.parse_args()
    if a.child:
        child_process(a.child)
    else:
        TONES = a.tones
        full_rate()
        if a.lo_table:
            lo_table(2 * a.trials)
        if a.snr_table:
            snr_table(a.trials)
