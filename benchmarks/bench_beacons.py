"""Beacon pipeline benchmark: start-up cost, cost per second of capture, real-time factor
and peak memory of full-rate captures, and association accuracy versus C/N0.

    python benchmarks/bench_beacons.py                 # 5, 20, 60 s at 2.4 MS/s (RTL-SDR cu8)
    python benchmarks/bench_beacons.py --durations 5 20 --repeat 3
    python benchmarks/bench_beacons.py --durations 5 20 --repeat 3 --baseline ../leonav-before
    python benchmarks/bench_beacons.py --snr-table     # + accuracy vs C/N0 (reduced rate, 10 trials each)
    python benchmarks/bench_beacons.py --lo-table      # + joint LO offset/drift error and combs (20 trials)

The captures are synthesized first (not timed) from the real Starlink element sets in
../shared/data/tle/starlink_2026-02-23.txt (9,543 satellites) at the paper's Rochester site.
Each one is then processed, side by side in this run:

  command      `leonav beacons CAPTURE --tle ... --no-figures` and the same with the figure,
               each in its own process: CPU (user + system, all threads) and peak RSS of that
               child from os.wait4, wall time beside it
  in-process   a fresh interpreter that imports the pipeline and times its stages with
               time.process_time (imports, element sets, STFT + tracking + association,
               CSV/JSON, figure)

Fixed cost and cost per second of capture are the intercept and slope of a least-squares
line through CPU seconds against capture seconds (a capture shorter than ~4.1 s is refused,
so the "0 s capture" is that line's value at 0). The real-time factor is capture seconds
over CPU seconds (and over wall seconds, which other load on the machine inflates). Figures
are the best of `--repeat` runs. Bytecode is cached in a temporary PYTHONPYCACHEPREFIX (as an
installed package has its .pyc files); one extra line shows a run that compiles every module
from source, as with PYTHONDONTWRITEBYTECODE=1.
"""
from __future__ import annotations

import argparse
import datetime as dt
import json
import logging
import os
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


def child_process(capture: str, out_dir: str, figures: bool) -> None:
    """Process one capture in this (fresh) interpreter; print JSON with CPU seconds per stage."""
    cpu = time.process_time
    c0, w0 = cpu(), time.perf_counter()
    _quiet()
    from leonav_runtime.beacons import capture_io, pipeline
    from leonav_runtime.beacons.predict import Site
    from leonav_runtime.orbits.elements import load_element_files

    c1 = cpu()
    elements = load_element_files([TLE])
    c2 = cpu()
    info = capture_io.open_capture(capture)
    res = pipeline.process_capture(info, elements, Site.from_degrees(*SITE_DEG))
    c3 = cpu()
    pipeline.write_outputs(res, Path(out_dir), figures=False)
    c4 = cpu()
    if figures:
        pipeline.plot_waterfall(res, Path(out_dir) / "waterfall.png")
    c5 = cpu()
    s = pipeline.summary(res)
    print(json.dumps({"imports": c1 - c0, "elements": c2 - c1, "process": c3 - c2, "write": c4 - c3,
                      "figure": c5 - c4, "cpu": c5 - c0, "wall": time.perf_counter() - w0,
                      "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                      "counts": s["counts"], "residual": s["rate_residual_abs_hz_s"],
                      "lo": {k: s["lo"][k] for k in ("offset_hz", "drift_hz_s", "drift_removed")},
                      "duration_s": info.duration_s, "bytes": info.path.stat().st_size}))


def _timed(argv: list[str], env: dict, cwd: str | None = None) -> dict:
    """CPU, wall and peak RSS of one child process (os.wait4 gives that child's own rusage)."""
    w0 = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, cwd=cwd)
    out = proc.stdout.read()
    err = proc.stderr.read()
    _, status, ru = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - w0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise SystemExit(f"{' '.join(map(str, argv))} failed ({proc.returncode}):\n{err.decode().strip()}")
    return {"cpu": ru.ru_utime + ru.ru_stime, "wall": wall, "peak_rss_mb": ru.ru_maxrss / 1024,
            "out": out.decode()}


def _summary(folder: Path) -> dict:
    """summary.json without its provenance (the command lines differ)."""
    s = json.loads((folder / "summary.json").read_text())
    s.pop("provenance", None)
    return s


def _best(runs: list[dict]) -> dict:
    return min(runs, key=lambda r: r["cpu"])


def _line(x: list[float], y: list[float]) -> tuple[float, float]:
    """(intercept, slope) of the least-squares line y = a + b x."""
    b, a = np.polyfit(np.asarray(x, float), np.asarray(y, float), 1)
    return float(a), float(b)


def synthesize(path: Path, duration_s: float) -> tuple[object, float]:
    from leonav_runtime.beacons import synth
    from leonav_runtime.beacons.predict import Site
    from leonav_runtime.orbits import load_elements

    cfg = synth.SynthConfig(duration_s=duration_s, sample_rate_hz=2.4e6, cn0_dbhz=38.0, n_satellites=6, seed=11,
                            tones_per_satellite=TONES, full_comb_in_band=False)
    t0 = time.process_time()
    _, truth = synth.write_synthetic_capture(path, load_elements(TLE), Site.from_degrees(*SITE_DEG), START, cfg)
    return truth, time.process_time() - t0


def startup_and_real_time(durations: list[float], repeat: int, baseline: Path | None = None) -> None:
    """Command and in-process CPU per capture length; fixed cost, cost per second, real-time factor.
    With `baseline` (another checkout of leonav), its `leonav beacons --no-figures` is timed right
    after this tree's in every repeat and its outputs compared byte for byte."""
    _quiet()
    load = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        env["PYTHONPYCACHEPREFIX"] = str(tmp / "pyc")
        caps = {}
        for d in durations:
            caps[d] = tmp / f"c{d:g}.cu8"
            truth, t_synth = synthesize(caps[d], d)
            print(f"capture {d:g} s at 2.4 MS/s: {caps[d].stat().st_size / 1e6:.0f} MB cu8, 6 satellites x {TONES} "
                  f"tone(s) at 38 dB-Hz, LO drift 0.3 Hz/s (synthesized in {t_synth:.1f} s CPU, not timed)")
        leonav = [sys.executable, "-m", "leonav_runtime.cli", "beacons"]
        tle = ["--tle", str(TLE)]
        _timed(leonav + [str(caps[durations[0]])] + tle + ["--out", str(tmp / "warm")], env)  # writes the .pyc
        base = str(baseline) if baseline else None
        if base:
            _timed(leonav + [str(caps[durations[0]])] + tle + ["--no-figures", "--out", str(tmp / "bwarm")], env, base)
        rows = {}
        for d in durations:
            r = {"cmd": [], "cmd_fig": [], "inproc": [], "base": []}
            for k in range(repeat):
                r["cmd"].append(_timed(leonav + [str(caps[d])] + tle + ["--no-figures", "--out", str(tmp / f"n{d}")], env))
                if base:
                    r["base"].append(_timed(leonav + [str(caps[d])] + tle + ["--no-figures", "--out", str(tmp / f"b{d}")],
                                            env, base))
                r["cmd_fig"].append(_timed(leonav + [str(caps[d])] + tle + ["--out", str(tmp / f"f{d}")], env))
                ip = _timed([sys.executable, __file__, "--child", str(caps[d]), str(tmp / f"i{d}")], env)
                ip.update(json.loads(ip["out"].strip().splitlines()[-1]))
                r["inproc"].append(ip)
            rows[d] = {k: _best(v) for k, v in r.items() if v}
            same = all((tmp / f"n{d}" / f).read_bytes() == (tmp / f"f{d}" / f).read_bytes()
                       for f in ("associations.csv", "doppler_rate_measurements.csv"))
            rows[d]["same"] = same and not (tmp / f"n{d}" / "waterfall.png").exists()
            if base:
                rows[d]["same_as_base"] = all(
                    (tmp / f"n{d}" / f).read_bytes() == (tmp / f"b{d}" / f).read_bytes()
                    for f in ("associations.csv", "doppler_rate_measurements.csv",
                              "doppler_rate_measurements.columns.txt")) and _summary(tmp / f"n{d}") == _summary(tmp / f"b{d}")
        cold = _timed(leonav + [str(caps[durations[0]])] + tle + ["--no-figures", "--out", str(tmp / "cold")],
                      {**env, "PYTHONDONTWRITEBYTECODE": "1", "PYTHONPYCACHEPREFIX": str(tmp / "empty")})
    print(f"\nCPU seconds (user + system, all threads; best of {repeat}), load average at start "
          f"{load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f} on {os.cpu_count()} cores")
    print(" capture s | command --no-figures: CPU  wall  RSS MB  x real time (CPU, wall) | with figure: CPU  RSS MB "
          "x real time | in-process: imports elements process write figure | --no-figures same CSVs, no PNG")
    for d, r in rows.items():
        c, f, i = r["cmd"], r["cmd_fig"], r["inproc"]
        print(f" {d:9g} | {c['cpu']:26.2f} {c['wall']:5.2f} {c['peak_rss_mb']:7.0f} {d / c['cpu']:8.1f}x "
              f"{d / c['wall']:5.1f}x | {f['cpu']:16.2f} {f['peak_rss_mb']:7.0f} {d / f['cpu']:6.1f}x | "
              f"{i['imports']:19.2f} {i['elements']:8.2f} {i['process']:7.2f} {i['write']:5.2f} {i['figure']:6.2f}"
              f" | {r['same']}")
    ds = list(rows)
    if len(ds) >= 2:
        print("\nleast-squares line CPU = fixed + per_second x capture seconds:")
        for label, key, sub in (("command --no-figures", "cmd", "cpu"), ("command with figure", "cmd_fig", "cpu"),
                                ("in-process, no figure", "inproc", None)):
            y = [rows[d][key][sub] if sub else rows[d][key]["cpu"] - rows[d][key]["figure"] for d in ds]
            a, b = _line(ds, y)
            print(f"  {label:22s} fixed {a:5.2f} s, {b * 1e3:5.1f} ms CPU per second of capture "
                  f"({1 / b:5.1f}x real time once started)")
        i0 = rows[ds[0]]["inproc"]
        print(f"  fixed parts in-process: imports {i0['imports']:.2f} s, element sets (9,543 TLEs) "
              f"{i0['elements']:.2f} s; the figure {np.mean([rows[d]['inproc']['figure'] for d in ds]):.2f} s")
    print(f"  every module compiled from source (PYTHONDONTWRITEBYTECODE=1), {durations[0]:g} s capture: "
          f"{cold['cpu']:.2f} s CPU against {rows[durations[0]]['cmd']['cpu']:.2f} s with cached bytecode")
    if base:
        print(f"\nside by side with {base} (its `leonav beacons --no-figures` timed right after this tree's, "
              f"every repeat; best of {repeat}):")
        print(" capture s | before: CPU  wall  RSS MB  x real time | now: CPU  x real time | now/before CPU | "
              "outputs identical")
        for d in ds:
            b, c = rows[d]["base"], rows[d]["cmd"]
            print(f" {d:9g} | {b['cpu']:12.2f} {b['wall']:5.2f} {b['peak_rss_mb']:7.0f} {d / b['cpu']:9.1f}x | "
                  f"{c['cpu']:8.2f} {d / c['cpu']:9.1f}x | {c['cpu'] / b['cpu']:14.2f} | {rows[d]['same_as_base']}")
        if len(ds) >= 2:
            for label, key in (("before", "base"), ("now", "cmd")):
                a, b = _line(ds, [rows[d][key]["cpu"] for d in ds])
                print(f"  {label:6s} fixed {a:5.2f} s, {b * 1e3:5.1f} ms CPU per second of capture")
    rss = ", ".join(f"{rows[d]['cmd']['peak_rss_mb']:.0f}" for d in ds)
    print(f"  peak RSS {rss} MB for {', '.join(f'{d:g}' for d in ds)} s captures (command, --no-figures); "
          f"ridges of the longest: {rows[max(rows)]['inproc']['counts']}")


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
    ap.add_argument("--child", nargs=2, metavar=("CAPTURE", "OUT"), help=argparse.SUPPRESS)
    ap.add_argument("--durations", type=float, nargs="+", default=[5.0, 20.0, 60.0], metavar="S",
                    help="capture lengths at 2.4 MS/s, s (default 5 20 60; at least 4.2)")
    ap.add_argument("--repeat", type=int, default=1, help="runs per capture and way; the best is shown")
    ap.add_argument("--snr-table", action="store_true", help="also print accuracy versus C/N0")
    ap.add_argument("--lo-table", action="store_true", help="also print the joint LO fit table")
    ap.add_argument("--tones", type=int, default=1, help="tones per satellite in the full-rate captures")
    ap.add_argument("--trials", type=int, default=10)
    ap.add_argument("--baseline", type=Path, default=None, metavar="TREE",
                    help="another leonav checkout (e.g. the code before a change): its command is timed side by "
                         "side and its outputs compared")
    a = ap.parse_args()
    if a.child:
        child_process(a.child[0], a.child[1], figures=True)
    else:
        TONES = a.tones
        startup_and_real_time(sorted(a.durations), max(1, a.repeat), a.baseline)
        if a.lo_table:
            lo_table(2 * a.trials)
        if a.snr_table:
            snr_table(a.trials)
