"""`leonav run DATASET.toml`: every mode and outage run of a dataset, scored, with files.

Writes into the results folder: metrics.json (scores per mode, two GNSS-alone baselines: hold
the last fix and interpolate between fixes; outages, fix NIS, the estimated fix latency with its
sigma, time per IMU step, counts of skipped rows, alignment and calibration reports, the scoring
settings used), errors.csv (per reference epoch and mode), trajectory_<mode>.csv/.pos/.kml/.gpx
and trajectory_<mode>_outage_<start>s.* for each outage run,
error_vs_time.png (outages shaded), error_cdf.png, trajectory.png.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from leonav_runtime.common import output
from leonav_runtime.dataset import checks, load, plots, runner, scoring
from leonav_runtime.scoring import export
from leonav_runtime.dataset.spec import DatasetSpec
from leonav_runtime.common.errors import UserInputError

GOALS = {"kf_gins_horizontal_rmse_m": 0.947, "yaw_rmse_deg": 5.0, "outage_median_ratio": 0.5,
         "kf_gins_us_per_imu_step": 14.6, "nis_band": [0.5, 2.0]}
"""Issue 11's Done-when figures (KF-GINS on the CPET run, as quoted there)."""
LATENCY_WARN_S = 1.0
"""An estimated fix latency beyond this (s) is more likely a wrong time base or IMU clock offset."""


def _slug(mode: str) -> str:
    return mode.replace("+", "_")


def run_dataset(spec: DatasetSpec, out_dir: Path, reference: dict | None = None, t_end_s: float | None = None,
                outages: bool = True, files: bool = True, progress: Callable[[str], None] | None = None) -> dict:
    """Run and score the dataset (module doc); returns the metrics. reference: a `[reference]`
    mapping with a `path` (the --reference file) replacing the description's; t_end_s: cut."""
    say = progress or (lambda _msg: None)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    say("reading files")
    ds = load.load(spec)
    if reference is not None:
        ds.reference = load.reference_from_file(Path(reference["path"]), reference, ds.t0_unix, ds.origin, ds.counts,
                                                spec["gnss"]["geoid_separation_m"])
    ref = ds.reference
    if ref is None:
        raise UserInputError(f"{spec.source}: no reference trajectory: set [reference] file or give --reference FILE")
    checks.reference(ref, ds.fixes, "--reference-crs / --reference-columns of --reference " + str(reference["path"])
                     if reference is not None else spec.where("reference", "crs") + " / position_columns / time_column")
    if t_end_s is not None:
        checks.until(t_end_s, float(ref.t[0]), "the reference starts")
        keep = ref.t <= t_end_s
        ref = ds.reference = load.Reference(ref.t[keep], ref.p_enu_m[keep],
                                            None if ref.yaw_rad is None else ref.yaw_rad[keep], ref.source)
    say("alignment and records")
    prep = runner.prepare(ds, t_end_s=t_end_s)
    L = prep.nav.layout
    sc = scoring.settings(spec["scoring"], prep.imu.t, prep.all_fixes.t)
    from leonav_runtime.common.provenance import provenance

    metrics: dict = {"provenance": provenance(), "dataset": spec.name, "description": spec.description, "source": spec.source,
                     "reference": ref.source, "reference_epochs": int(ref.t.size), "t0_unix_s": ds.t0_unix,
                     "origin_deg_m": [float(np.degrees(ds.origin[0])), float(np.degrees(ds.origin[1])), ds.origin[2]],
                     "counts": ds.counts | {"records": {k: int(v.size) for k, v in prep.streams.items()}},
                     "notes": prep.inputs.notes, "goals_issue_11": GOALS, "scoring": sc} | prep.report
    gps_err = scoring.hold_last_fix(prep.all_fixes, ref.t) - ref.p_enu_m
    metrics["gps_alone"] = scoring.error_stats(gps_err)
    # the second GNSS-alone baseline: holding a fix lags by up to a fix interval, which can hide a late tag
    interp_err = scoring.interpolated_fix(prep.all_fixes, ref.t) - ref.p_enu_m
    metrics["gps_alone_interpolated"] = scoring.error_stats(interp_err)
    series, modes, tracks = {}, {}, {}
    for mode in spec["filter"]["modes"]:
        say(f"run {mode}")
        recs, res, seconds, run_report = runner.run_mode(prep, mode)
        scores, series[mode] = scoring.run_scores(res, L, ref, sc["yaw_skip_s"])
        nis = {k: runner.fix_nis(prep, res, (k,)) for k in runner.FIX_KINDS}
        scores["fix_nis_mean"] = scoring.fix_nis_stats(nis)
        if spec["gnss"]["time_offset_s"] == "estimate":
            scores["fix_latency_s"] = lat = scoring.latency_estimate(res, L)
            if abs(lat["value"]) > LATENCY_WARN_S:
                prep.inputs.notes.append(
                    f"WARNING: {mode}: estimated fix latency {lat['value']:+.2f} +- {lat['sigma']:.2f} s is beyond "
                    f"+-{LATENCY_WARN_S:g} s: a receiver's latency is tens of ms; check the time bases and "
                    f"{spec.where('imu', 'time_offset_s')} (a clock offset is not a latency)")
        scores["records"] = {"total": int(recs.size), "imu": res.n_imu, "applied": res.n_applied,
                             "gated": res.n_gated, "failed": res.n_failed} | run_report
        scores["filter_seconds"] = seconds
        scores["us_per_imu_step"] = seconds / max(res.n_imu, 1) * 1e6
        if files:
            traj = export.trajectory(res, L, ds.origin, ds.t0_unix, prep.inputs.init["start_s"],
                                     spec["filter"]["output_rate_hz"])
            tracks[mode] = traj["p_enu"]
            scores["files"] = [p.name for p in export.write_all(out_dir / f"trajectory_{_slug(mode)}", traj,
                                                                 f"{spec.name} {mode}", [spec.source])]
        modes[mode] = scores
    metrics["modes"] = modes
    outage_series: dict = {}
    if outages and sc["outage_starts_s"]:
        for mode in spec["filter"]["modes"]:
            runs = {}
            for start in sc["outage_starts_s"]:
                if start + sc["outage_length_s"] > ref.t[-1] or start < prep.inputs.init["start_s"]:
                    continue
                say(f"run {mode}, outage at {start:g} s")
                runs[start] = runner.run_mode(prep, mode, (start, start + sc["outage_length_s"]))[1]
                if files:
                    traj = export.trajectory(runs[start], L, ds.origin, ds.t0_unix, prep.inputs.init["start_s"],
                                             spec["filter"]["output_rate_hz"])
                    name = f"trajectory_{_slug(mode)}_outage_{start:g}s"
                    written = export.write_all(out_dir / name, traj, f"{spec.name} {mode}, fixes removed over "
                                               f"[{start:g}, {start + sc['outage_length_s']:g}) s", [spec.source])
                    modes[mode].setdefault("outage_files", []).extend(p.name for p in written)
            modes[mode]["outages"] = scoring.outage_scores(prep.all_fixes, ref, sc["outage_starts_s"],
                                                           sc["outage_length_s"], runs, L)
            outage_series[mode] = {s: scoring.run_scores(r, L, ref, sc["yaw_skip_s"])[1] for s, r in runs.items()}
    metrics["summary"] = summary(metrics)
    if files:
        say("writing files")
        _write_files(out_dir, metrics, series, outage_series, gps_err, prep, ref, spec, tracks, sc)
    output.write_json(out_dir / "metrics.json", metrics)
    return metrics


def best_mode(metrics: dict) -> str:
    """The last mode given (the one with every stream the description asks for)."""
    return list(metrics["modes"])[-1]


def summary(metrics: dict) -> dict:
    """Issue 11's goals, each with the value reached and whether it is met."""
    mode = best_mode(metrics)
    m = metrics["modes"][mode]
    out = {"mode": mode}
    h = m["rmse_horizontal_m"]
    baselines = [b["rmse_horizontal_m"] for b in (metrics["gps_alone"], metrics.get("gps_alone_interpolated", {}))
                 if b.get("rmse_horizontal_m") is not None]
    better = min(baselines) if baselines else None
    out["horizontal_rmse_m"] = {"value": h, "gps_alone": metrics["gps_alone"]["rmse_horizontal_m"],
                                "gps_alone_interpolated": metrics.get("gps_alone_interpolated", {}).get(
                                    "rmse_horizontal_m"),
                                "ratio_to_better_gps_alone": h / better if h is not None and better else None,
                                "met": h is not None and h < GOALS["kf_gins_horizontal_rmse_m"]
                                and better is not None and h < better}
    y = m.get("rmse_yaw_deg_after_skip")
    out["yaw_rmse_deg_after_skip"] = {"value": y, "met": None if y is None else y <= GOALS["yaw_rmse_deg"]}
    o = m.get("outages")
    if o:
        scored = o["median_ratio"] is not None
        out["outages"] = {"median_ratio": o["median_ratio"],
                          "worse_than_hold": o["worse_than_hold"] if scored else None,
                          "met": (o["median_ratio"] <= GOALS["outage_median_ratio"] and o["worse_than_hold"] == 0)
                          if scored else None}
    us = m["us_per_imu_step"]
    out["us_per_imu_step"] = {"value": us, "met": us < GOALS["kf_gins_us_per_imu_step"]}
    nis = m["fix_nis_mean"]["all"]
    out["fix_nis_mean"] = {"value": nis, "met": nis is not None and GOALS["nis_band"][0] <= nis <= GOALS["nis_band"][1]}
    return out


def _write_files(out_dir: Path, metrics: dict, series: dict, outage_series: dict, gps_err: np.ndarray, prep, ref,
                 spec: DatasetSpec, tracks: dict, sc: dict) -> None:
    header = ["t_s", "gps_alone_horizontal_m"] + [f"{m}_{c}" for m in series for c in
                                                   ("e_m", "n_m", "u_m", "horizontal_m", "sigma_e_m", "sigma_n_m",
                                                    "yaw_err_deg")]
    rows = []
    for i, t in enumerate(ref.t):
        row = [f"{t:.3f}", f"{np.hypot(*gps_err[i, :2]):.4f}"]
        for s in series.values():
            e, sg = s["err_enu"][i], s["sigma_enu"][i]
            row += [f"{v:.4f}" for v in e] + [f"{np.hypot(e[0], e[1]):.4f}", f"{sg[0]:.4f}", f"{sg[1]:.4f}",
                                              f"{np.degrees(s['yaw_err_rad'][i]):.3f}"]
        rows.append(row)
    output.write_csv(out_dir / "errors.csv", header, rows)
    gps = {"t": ref.t, "err_enu": gps_err, "hold_outage": {}}
    length = sc["outage_length_s"]
    for start in next(iter(outage_series.values()), {}):
        tt = ref.t[(ref.t >= start) & (ref.t <= start + length)]
        k = np.searchsorted(prep.all_fixes.t, start) - 1
        gps["hold_outage"][start] = {"t": tt, "err_h": np.hypot(*(prep.all_fixes.p_enu_m[k, :2] -
                                                                  scoring.reference_at(ref, tt)[:, :2]).T)}
    best = best_mode(metrics)
    s = metrics["summary"]
    title = (f"{spec.name}: {best} horizontal RMSE {plots.fmt(s['horizontal_rmse_m']['value'])} m "
             f"(GPS alone {plots.fmt(s['horizontal_rmse_m']['gps_alone'])} m)")
    plots.error_vs_time(out_dir / "error_vs_time.png", series, gps, outage_series, length, title)
    plots.error_cdf(out_dir / "error_cdf.png", series, gps, f"{spec.name}: horizontal error CDF at the "
                    f"{ref.t.size} reference epochs")
    plots.trajectory_on_reference(out_dir / "trajectory.png", ref.p_enu_m, prep.all_fixes.p_enu_m, tracks,
                                  f"{spec.name}: trajectories on the reference (ENU at the first fix)")


def score_reference_file(reference: dict, results: dict, fixes, epoch_unix: float | None, origin, layout,
                         out_dir: Path) -> dict:
    """Score runs made elsewhere (`leonav replay`) against a --reference file, as `leonav run` does:
    results {mode: RunResult} on the axis of seconds since `epoch_unix`, ENU at `origin`; fixes
    (FixTable, same axis) for GPS alone and the distance check. Writes errors_reference.csv and
    error_cdf_reference.png into out_dir; returns the scores."""
    path = Path(reference["path"])
    if epoch_unix is None or origin is None:
        raise UserInputError(f"--reference {path}: the session has no UTC epoch or ENU origin (no GNSS fix with a "
                             "date): the reference cannot be placed on its time axis")
    counts: dict = {}
    ref = load.reference_from_file(path, reference, epoch_unix, origin, counts)
    if fixes.t.size:
        checks.reference(ref, fixes, f"--reference-crs / --reference-columns of --reference {path}")
    modes, series = {}, {}
    for mode, res in results.items():
        modes[mode], series[mode] = scoring.run_scores(res, layout, ref, 0.0)
    out = {"path": str(path), "epochs": int(ref.t.size), "counts": counts, "modes": modes}
    header = ["t_s"] + [f"{m}_{c}" for m in series for c in ("e_m", "n_m", "u_m", "horizontal_m")]
    rows = [[f"{t:.3f}"] + [f"{v:.4f}" for s in series.values() for v in (*s["err_enu"][i],
                                                                         np.hypot(*s["err_enu"][i, :2]))]
            for i, t in enumerate(ref.t)]
    output.write_csv(out_dir / "errors_reference.csv", header, rows)
    if fixes.t.size:
        gps_err = scoring.hold_last_fix(fixes, ref.t) - ref.p_enu_m
        out["gps_alone"] = scoring.error_stats(gps_err)
        out["gps_alone_interpolated"] = scoring.error_stats(scoring.interpolated_fix(fixes, ref.t) - ref.p_enu_m)
        plots.error_cdf(out_dir / "error_cdf_reference.png", series, {"err_enu": gps_err},
                        f"horizontal error CDF against {path.name} ({ref.t.size} epochs)")
    return out
