"""Running a study: every cell x mode on an executor, then the table, JSON and figure.

A task is (cell scenario, mode, count, a block of trial indices), the sweep's own work unit
(`montecarlo.run_block`), so a study runs on the same executors (local process pool, Dask)
and trial i of every cell draws from the same seed stream (common random numbers across
cells: differences between cells are the varied field's, not the draw's). The block with
trial 0 also computes the cell's PCRB along its truth.

Writes into the results folder:
- `study.csv`: one row per (cell, mode): the varied values, position RMSE and sqrt(PCRB)
  time-averaged over the run and at its final epoch, velocity and attitude the same, NEES;
- `study.json`: the study as run, the same numbers per cell, timings;
- `study.png`: a heat map per mode (2 varied fields) or lines (1 field), time-averaged and
  final-epoch RMSE with sqrt(PCRB);
- `study.toml`: the study file as given, or with `--set` / `--trials` applied when they changed it
  (rerunning it repeats the run);
- `report.html`: the table and the figure in one self-contained page.
Metric keys carry their unit and name the bound as a square root (`position_rmse_m`,
`position_sqrt_pcrb_m`, `velocity_final_rmse_mps`, `attitude_final_sqrt_pcrb_deg`).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

from leonav_runtime.sweep import montecarlo as mc
from leonav_runtime.common import output
from leonav_runtime.sweep.executors import make_executor, map_in_order
from leonav_runtime.scenarios.load import check_run_size
from leonav_runtime.study.spec import Study

BLOCK_TRIALS = 50   # a whole cell per task at the usual 20 trials: one setup per task
# block -> (unit suffix of its keys, scale from the summaries' SI value)
BLOCK_UNITS = {"position": ("m", 1.0), "velocity": ("mps", 1.0), "attitude": ("deg", 180.0 / math.pi),
               "vertical": ("m", 1.0)}
# summary field -> key infix: the bound is a square root (sqrt(PCRB) in the unit of the RMSE)
KINDS = {"rmse": "rmse", "pcrb": "sqrt_pcrb", "final_rmse": "final_rmse", "final_pcrb": "final_sqrt_pcrb"}


def metric_key(block: str, kind: str) -> str:
    """Column/key name of a study metric with its unit, e.g. ("position", "pcrb") ->
    "position_sqrt_pcrb_m", ("attitude", "final_rmse") -> "attitude_final_rmse_deg"."""
    return f"{block}_{KINDS[kind]}_{BLOCK_UNITS[block][0]}"


@dataclass
class StudyResult:
    """Per (cell index, mode): the summary row; timing of the run."""

    rows: dict[tuple[tuple[int, ...], str], dict]
    timing: dict


def _tasks(study: Study) -> list[tuple]:
    tasks = []
    for cell in study.cells:
        scn = cell.scenario
        for mode in study.modes:
            for start in range(0, study.trials, BLOCK_TRIALS):
                idx = list(range(start, min(study.trials, start + BLOCK_TRIALS)))
                tasks.append(((cell.index, mode), (scn.raw, scn.source, str(Path(study.base.source).parent),
                                                   mode, cell.count, idx)))
    return tasks


def _row(summary: dict) -> dict:
    row = {"trials": summary["trials"], "gated": summary["gated"], "failed": summary["failed"]}
    for block, (_, scale) in BLOCK_UNITS.items():
        b = summary[block]
        for k in KINDS:
            row[metric_key(block, k)] = scale * b[k]
    n = summary["nees"]
    row.update(nees_mean=n["mean"], nees_lo=n["band95"][0], nees_hi=n["band95"][1],
               nees_fraction_inside=n["fraction_inside"])
    nis = summary["nis"]
    row["nis_mean"] = {str(k): v["mean"] for k, v in nis.items()}
    return row


def run_study(study: Study, out_dir: Path, *, workers: int | None = None, dask_address: str | None = None,
              progress: bool = True, figures: bool = True) -> StudyResult:
    """Run every cell and mode of `study` and write the results folder (see module doc)."""
    for cell in study.cells:   # memory per run, before any work is sent out
        check_run_size(cell.scenario, trials=min(study.trials, BLOCK_TRIALS), workers=1 if dask_address else workers)
    t_start = time.perf_counter()
    tasks = _tasks(study)
    bar = None
    if progress:
        from leonav_runtime.common.progress import progress as make_progress

        bar = make_progress(len(tasks), f"study {study.name}", "task", smoothing=0.05)
    with make_executor(workers, dask_address) as ex:
        blocks = map_in_order(ex, mc.run_block, [t for _, t in tasks], on_done=(bar.update if bar else None))
    if bar:
        bar.close()
    results: dict = {}
    bounds: dict = {}
    for (key, _), block in zip(tasks, blocks):
        results.setdefault(key, []).extend(block.results)
        if block.pcrb is not None:
            bounds[key] = block.pcrb
    rows = {key: _row(mc.summarize(res, bounds[key])) for key, res in results.items()}
    n_trials = sum(len(b.results) for b in blocks)
    cpu = sum(b.seconds for b in blocks)
    timing = {"wall_s": time.perf_counter() - t_start, "trials_run": n_trials, "cells": len(study.cells),
              "trial_cpu_ms": 1e3 * cpu / max(n_trials, 1),
              "trial_wall_ms": 1e3 * sum(b.wall_seconds for b in blocks) / max(n_trials, 1),
              "clock": "trial_cpu_ms: the worker thread's CPU clock; trial_wall_ms, wall_s: wall time",
              "executor": f"dask {dask_address}" if dask_address else f"process pool ({workers or 'all cores'})"}
    result = StudyResult(rows, timing)
    write_results(study, out_dir, result, figures=figures)
    return result


def write_effective_study(study: Study, path: Path) -> None:
    """The study file as given (comments kept) or, when --set/--trials changed it, the
    effective study as TOML."""
    import copy

    import tomli_w

    src = Path(study.source)
    changed = (study.trials != study.raw.get("trials", study.base.trials)
               or dict(study.sets) != dict(study.raw.get("set", {})))
    if src.is_file() and not changed:
        path.write_text(src.read_text())
        return
    effective = copy.deepcopy(study.raw)
    effective["trials"] = study.trials
    scenario = effective.get("scenario")
    if isinstance(scenario, str) and (src.parent / scenario).is_file():  # still found from the results folder
        effective["scenario"] = str((src.parent / scenario).resolve())
    if study.sets:
        effective["set"] = dict(study.sets)
    path.write_text(f"# effective study of this run (from {study.source}, changed by --set/--trials)\n"
                    + tomli_w.dumps(effective))


def write_results(study: Study, out_dir: Path, res: StudyResult, figures: bool = True) -> None:
    """study.csv, study.json, study.toml and study.png."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_effective_study(study, out_dir / "study.toml")
    keys = [a.key for a in study.axes]
    metric_keys = [k for k in next(iter(res.rows.values())) if k != "nis_mean"]
    csv_rows, cells = [], []
    for cell in study.cells:
        for mode in study.modes:
            row = res.rows[(cell.index, mode)]
            csv_rows.append([cell.values[k] for k in keys] + [mode, cell.count] + [row[k] for k in metric_keys])
            cells.append({"values": cell.values, "mode": mode, "count": cell.count, **row})
    output.write_csv(out_dir / "study.csv", keys + ["mode", "count"] + metric_keys, csv_rows)
    from leonav_runtime.common.provenance import provenance

    meta = {"provenance": provenance(study.base.raw), "name": study.name, "description": study.description, "source": study.source,
            "base_scenario": study.base.source, "modes": study.modes, "trials_per_cell": study.trials,
            "set": study.sets, "axes": [{"key": a.key, "label": a.label, "values": list(a.values)} for a in study.axes],
            "units": {"_m": "m (position)", "_mps": "m/s (velocity)", "_deg": "deg (attitude)",
                      "rmse": "root mean square over trials and the output grid (10 Hz) of the run",
                      "final_rmse": "over trials at the last output epoch",
                      "sqrt_pcrb": "sqrt of the posterior CRB trace, time-averaged like rmse",
                      "final_sqrt_pcrb": "sqrt of the posterior CRB trace at the last output epoch",
                      "nees": "normalized estimation error squared of the 9D error, mean over trials and time"},
            "timing": res.timing, "cells": cells}
    output.write_json(out_dir / "study.json", meta)
    if figures:
        from leonav_runtime.study import plots

        plots.plot_study(study, res.rows, out_dir / "study.png")
    from leonav_runtime.common.html_report import write_study_report

    write_study_report(out_dir, meta)


def summary_table(study: Study, res: StudyResult) -> str:
    """Position RMSE / sqrt(PCRB), time-averaged and final, per cell and mode (plain text)."""
    from leonav_runtime.common.text_table import text_table

    keys = [a.key for a in study.axes]
    rows = []
    for cell in study.cells:
        for mode in study.modes:
            r = res.rows[(cell.index, mode)]
            rows.append([*(cell.values[k] for k in keys), mode, cell.count,
                         f"{r['position_rmse_m']:.2f}", f"{r['position_sqrt_pcrb_m']:.2f}",
                         f"{r['position_final_rmse_m']:.2f}", f"{r['position_final_sqrt_pcrb_m']:.2f}",
                         f"{r['nees_mean']:.2f}", f"[{r['nees_lo']:.2f}, {r['nees_hi']:.2f}]"])
    header = [*keys, "mode", "N", "RMSE", "sqrt(PCRB)", "final RMSE", "final sqrt(PCRB)", "NEES", "95 % band"]
    lines = [f"study {study.name}: {len(study.cells)} cells x {len(study.modes)} modes, {study.trials} trials each",
             "position, m: RMSE and sqrt(PCRB) time-averaged and at the final epoch; N: Starlink satellites; "
             "NEES: of the 9D error, mean over trials and time, with its 95 % band"]
    lines += ["  " + line for line in text_table(header, rows, "r" * len(keys) + "lrrrrrrl")]
    t = res.timing
    lines.append(f"{t['trials_run']} trials in {t['wall_s']:.1f} s wall ({t['trial_cpu_ms']:.1f} ms CPU per trial "
                 f"incl. setup, {t['executor']})")
    return "\n".join(lines)
