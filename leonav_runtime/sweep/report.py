"""A sweep's results folder and console summary.

Files (units in every CSV header; attitude in degrees, as printed on the console):
- `config.toml`: the scenario as given;
- `metrics.json`: provenance (version, commit, command line, scenario hash), the scenario,
  per mode and count RMSE / sqrt(PCRB) / ratio for position (m), velocity (m/s) and
  attitude (rad, with a deg copy), NEES and NIS with their 95 % chi-square bands,
  gated/failed counts, the findings and timings;
- `rmse.csv`: one row per (mode, count): time-averaged and final-epoch RMSE and sqrt(PCRB);
- `rmse_vs_time.csv`: per mode at every count, RMSE and sqrt(PCRB) on the output grid;
- `findings.csv`: the paper's findings and the scenario's checks, with the position RMSE
  both averaged over time and at the final epoch, and the paper's band;
- figures (`sweep_plots.py`) and `report.html` (`html_report.py`).
"""
from __future__ import annotations

import math
from pathlib import Path

from leonav.hardware.jsonfile import jsonable
from leonav_runtime.common import html_report
from leonav_runtime.sweep import montecarlo as mc
from leonav_runtime.common import output
from leonav_runtime.common.provenance import provenance

# block -> (column prefix, unit, scale from the SI value held in the summaries)
CSV_BLOCKS = {"position": ("pos", "m", 1.0), "velocity": ("vel", "mps", 1.0), "attitude": ("att", "deg", 180 / math.pi),
              "vertical": ("up", "m", 1.0)}
UNITS = {"position": "m", "velocity": "m/s", "attitude": "rad (attitude_deg: deg)", "vertical": "m (Up component)",
         "t_s": "s"}


def rmse_columns() -> list[str]:
    cols = ["mode", "count", "trials"]
    for prefix, unit, _ in CSV_BLOCKS.values():
        cols += [f"{prefix}_rmse_{unit}", f"{prefix}_sqrt_pcrb_{unit}", f"{prefix}_ratio",
                 f"{prefix}_final_rmse_{unit}", f"{prefix}_final_sqrt_pcrb_{unit}"]
    return cols


def rmse_rows(res) -> list[list]:
    rows = []
    for (mode, count), s in sorted(res.summaries.items()):
        row = [mode, count, s["trials"]]
        for block, (_p, _u, k) in CSV_BLOCKS.items():
            b = s[block]
            row += [k * b["rmse"], k * b["pcrb"], b["ratio"], k * b["final_rmse"], k * b["final_pcrb"]]
        rows.append(row)
    return rows


FINDINGS_COLUMNS = ["finding", "kind", "holds", "mode", "count", "position_rmse_time_avg_m",
                    "position_rmse_final_m", "paper_low_m", "paper_high_m"]


def findings_rows(findings: list[dict]) -> list[list]:
    rows = []
    for f in findings:
        band = f.get("paper_band_m") or ["", ""]
        for v in f.get("values") or [{}]:
            rows.append([f["finding"], f.get("kind", "paper"), f["holds"], v.get("mode", ""), v.get("count", ""),
                         v.get("position_rmse_time_avg_m", ""), v.get("position_rmse_final_m", ""), *band])
    return rows


def _sqrt_keys(block: dict) -> dict:
    """A summary block for metrics.json: the bound keys say they hold sqrt(PCRB)."""
    names = {"pcrb": "sqrt_pcrb", "final_pcrb": "final_sqrt_pcrb"}
    return {names.get(k, k): v for k, v in block.items() if not k.endswith("_t")}


def metrics_dict(scn, res) -> dict:
    """metrics.json content (also what the Python API returns as `metrics`)."""
    metrics = {
        "provenance": provenance(scn.raw),
        "scenario": {"name": scn.name, "source": scn.source, "epoch_utc": scn.epoch_utc,
                     "duration_s": scn.duration_s, "trials": scn.trials, "modes": scn.modes,
                     "counts": scn.starlink["counts"]},
        "units": UNITS,
        "findings": res.findings,
        "notes": res.notes,  # e.g. satellites SGP4 could not propagate, left out by name
        "timing": res.timing,
        "results": [],
    }
    # the scenario's mode order (as the console table), counts ascending: not alphabetical
    order = {m: i for i, m in enumerate(scn.modes)}
    for (mode, count), s in sorted(res.summaries.items(), key=lambda kv: (order.get(kv[0][0], len(order)), kv[0])):
        entry = {"mode": mode, "count": count, "trials": s["trials"], "gated": s["gated"], "failed": s["failed"],
                 "front_end": s.get("front_end", {}),   # slips injected / detected, epochs dropped (all trials)
                 "orbit_states": s.get("orbit_states", {}),   # slots taken / reused, records without one (method 1)
                 "nees": {k: v for k, v in s["nees"].items() if k != "nees_t"},
                 "nis": {str(k): v for k, v in s["nis"].items()}}
        for block in mc.BLOCKS:
            entry[block] = _sqrt_keys(s[block])
            if block == "attitude":
                entry["attitude_deg"] = {k: math.degrees(v) for k, v in entry[block].items() if k != "ratio"}
        metrics["results"].append(entry)
    return metrics


def write_config(scn, path: Path) -> None:
    """config.toml: the scenario file as given (comments kept) or, when the run changed it
    (command-line options, the Python API), the effective scenario."""
    import tomli_w

    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib

    src = Path(scn.source)
    text = src.read_text() if src.is_file() else None
    if text is not None and tomllib.loads(text) == scn.raw:
        path.write_text(text)
        return
    head = f"# effective scenario of this run (from {scn.source}, changed by the run's options)\n"
    path.write_text(head + tomli_w.dumps(scn.raw))


def write_results(scn, out_dir: Path, res, figures: bool = True) -> None:
    """Every file of the module doc into `out_dir`."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_config(scn, out_dir / "config.toml")
    time_rows = []
    for (mode, count), s in sorted(res.summaries.items()):
        for i, t in enumerate(res.t_eval):
            vals = [s[b][k][i] * CSV_BLOCKS[b][2] for b in CSV_BLOCKS for k in ("rmse_t", "pcrb_t")]
            time_rows.append([mode, count, t, *vals, s["nees"]["nees_t"][i]])
    metrics = metrics_dict(scn, res)
    output.write_json(out_dir / "metrics.json", metrics)
    output.write_csv(out_dir / "rmse.csv", rmse_columns(), rmse_rows(res))
    output.write_csv(out_dir / "findings.csv", FINDINGS_COLUMNS, findings_rows(res.findings))
    output.write_csv(out_dir / "rmse_vs_time.csv",
                     ["mode", "count", "t_s", *(f"{p}_{k}_{u}" for p, u, _ in CSV_BLOCKS.values()
                                                 for k in ("rmse", "sqrt_pcrb")), "nees_mean"], time_rows)
    if figures:   # matplotlib only then: its import is ~0.2 s of CPU a run without figures does not need
        from leonav_runtime.sweep import plots as sweep_plots

        sweep_plots.plot_all(scn, res, out_dir)
    # the content of metrics.json, not read back; without figures, no PNG an earlier run left in the folder
    html_report.write_sweep_report(out_dir, jsonable(metrics), figures=figures)


def summary_table(res) -> str:
    """Human summary: RMSE / sqrt(PCRB) per mode and count, the paper's findings (time-averaged
    and final-epoch RMSE), then the scenario's own checks."""
    scn = res.scenario  # as run (e.g. with --trials)
    counts = scn.starlink["counts"]
    lines = [f"position RMSE / sqrt(PCRB), m  ({scn.trials} trials per point)",
             f"{'mode':24s}" + "".join(f"{c:>14d}" for c in counts)]
    for mode in scn.modes:
        cells = []
        for c in counts:
            p = res.summaries[(mode, c)]["position"]
            cells.append(f"{p['rmse']:6.2f}/{p['pcrb']:<6.2f} ")
        lines.append(f"{mode:24s}" + "".join(f"{x:>14s}" for x in cells))
    hi = counts[-1]
    lines.append(f"\nat {hi} satellites: velocity m/s, attitude deg, NEES (95 % band); each pair is RMSE/sqrt(PCRB), "
                 "(xR) and pos xR their ratio RMSE / sqrt(PCRB) (1: the filter reaches its bound)")
    for mode in scn.modes:
        s = res.summaries[(mode, hi)]
        v, a, n = s["velocity"], s["attitude"], s["nees"]
        lines.append(f"  {mode:24s} vel {v['rmse']:.3f}/{v['pcrb']:.3f} (x{v['ratio']:.2f})  "
                     f"att {math.degrees(a['rmse']):.3f}/{math.degrees(a['pcrb']):.3f}  "
                     f"pos x{s['position']['ratio']:.2f}  NEES {n['mean']:.2f} "
                     f"[{n['band95'][0]:.2f}, {n['band95'][1]:.2f}]")
    for kind, title in (("paper", "the paper's findings (position RMSE averaged over time; final epoch in "
                                  "brackets where the paper gives a band):"),
                        ("scenario", "this scenario's checks (not from the paper):")):
        chosen = [f for f in res.findings if f.get("kind", "paper") == kind]
        if chosen:
            lines.append("\n" + title)
        for f in chosen:
            lines.append(f"  [{'holds' if f['holds'] else 'DIFFERS'}] {f['finding']}: {f['detail']}")
    t = res.timing
    lines.append(f"\n{t['trials_run']} trials in {t['trials_wall_s']:.1f} s wall, {t['total_cpu_s']:.1f} s CPU = "
                 f"{t['cpu_over_floor']:.2f}x the C floor ({t['trials_run']} trials x {t['imu_steps_per_trial']} IMU "
                 f"steps x {t['c_us_per_imu_step']:.2f} us = {t['floor_cpu_s']:.1f} s); total {t['wall_s']:.1f} s wall")
    return "\n".join(lines)
