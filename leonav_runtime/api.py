"""The Python API behind `import leonav`: load a scenario, run a sweep or a replay in
memory, run a study (a grid over scenario fields) or a recorded dataset and get plain dicts and NumPy arrays whose key names carry their units
(`position_rmse_m`, `attitude_rmse_deg`, `t_s`). Nothing is written unless `out_dir` is
given; then the same results folder as the command line (with report.html) is written.

    import leonav
    scn = leonav.load_scenario("paper", counts=[5, 45], modes=["gps+imu", "leo-alpha+imu"])
    res = leonav.run_sweep(scn, trials=10)
    res["position_rmse_m"]          # (modes, counts) array, metres
"""
from __future__ import annotations

import csv
import math
import tempfile
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.scenarios.load import MODES, SCHEMA, Scenario
from leonav_runtime.scenarios.load import load_scenario as _load_scenario

__all__ = ["MODES", "Scenario", "load_scenario", "run_sweep", "run_replay", "run_study", "run_dataset"]

# block -> (key prefix, unit suffix, scale from the SI value in the summaries)
_BLOCKS = {"position": ("position", "m", 1.0), "velocity": ("velocity", "mps", 1.0),
           "attitude": ("attitude", "deg", 180.0 / math.pi), "vertical": ("vertical", "m", 1.0)}


_TRIALS = SCHEMA["monte_carlo"]["trials"]   # the bounds of the scenario's [monte_carlo] trials and of --trials


def _check_run_options(trials: int | None, workers: int | None) -> None:
    """The same limits as the command line's --trials and --workers (UserInputError)."""
    if trials is not None and (not isinstance(trials, (int, np.integer)) or isinstance(trials, bool)
                               or not _TRIALS.lo <= trials <= _TRIALS.hi):
        raise UserInputError(f"trials = {trials!r}: expected an integer in {_TRIALS.lo:g}..{_TRIALS.hi:g}")
    if workers is not None and (not isinstance(workers, (int, np.integer)) or isinstance(workers, bool) or workers < 1):
        raise UserInputError(f"workers = {workers!r}: expected an integer >= 1 (or None: all cores)")


def load_scenario(name_or_path: str | Path = "paper", *, modes: Sequence[str] | None = None,
                  counts: Sequence[int] | None = None, seed: int | None = None,
                  trials: int | None = None) -> Scenario:
    """A built-in scenario by name (`paper`, `paper-hardware`, `maritime-outage`,
    `passive-phase-static`, `passive-phase-drive`, `passive-phase-base`) or a TOML file, with
    optional changes validated like the file's values (modes, Starlink counts, seed, trials)."""
    from leonav_runtime.scenarios.overrides import apply_overrides

    scn, _ = apply_overrides(_load_scenario(name_or_path), modes=modes, counts=counts, seed=seed, trials=trials,
                             api=True)
    return scn


def sweep_arrays(res) -> dict[str, Any]:
    """A `sweep.SweepResult` as plain dicts and arrays with units in the key names."""
    scn = res.scenario
    modes, counts = list(scn.modes), list(scn.starlink["counts"])
    out: dict[str, Any] = {"scenario": scn.name, "modes": modes, "counts": counts, "trials": scn.trials,
                           "t_s": np.asarray(res.t_eval, float)}
    table, curves = [], {}
    for block, (name, unit, k) in _BLOCKS.items():
        for kind, src in (("rmse", "rmse"), ("sqrt_pcrb", "pcrb"), ("final_rmse", "final_rmse"),
                          ("final_sqrt_pcrb", "final_pcrb")):
            out[f"{name}_{kind}_{unit}"] = np.array([[k * res.summaries[(m, c)][block][src] for c in counts]
                                                     for m in modes])
    out["nees_mean"] = np.array([[res.summaries[(m, c)]["nees"]["mean"] for c in counts] for m in modes])
    for m in modes:
        for c in counts:
            s = res.summaries[(m, c)]
            row = {"mode": m, "count": c, "trials": s["trials"], "gated": s["gated"], "failed": s["failed"],
                   "nees_mean": s["nees"]["mean"]}
            curve = {}
            for block, (name, unit, k) in _BLOCKS.items():
                b = s[block]
                row.update({f"{name}_rmse_{unit}": k * b["rmse"], f"{name}_sqrt_pcrb_{unit}": k * b["pcrb"],
                            f"{name}_final_rmse_{unit}": k * b["final_rmse"],
                            f"{name}_final_sqrt_pcrb_{unit}": k * b["final_pcrb"], f"{name}_ratio": b["ratio"]})
                curve[f"{name}_rmse_{unit}"] = k * np.asarray(b["rmse_t"])
                curve[f"{name}_sqrt_pcrb_{unit}"] = k * np.asarray(b["pcrb_t"])
            table.append(row)
            curves[(m, c)] = curve
    out.update({"table": table, "curves": curves, "findings": res.findings, "timing": res.timing,
                "truth_p_enu_m": np.asarray(res.truth_p_enu), "trial0_p_enu_m": dict(res.trajectories),
                "notes": list(res.notes)})
    return out


def run_sweep(scenario: Scenario | str | Path = "paper", *, trials: int | None = None, workers: int | None = 1,
              out_dir: str | Path | None = None, progress: bool = False, figures: bool = True) -> dict[str, Any]:
    """Run the scenario's Monte Carlo sweep and return `sweep_arrays` of it.

    `scenario`: a `Scenario` (see `load_scenario`) or its name/path. `workers`: local
    processes (1: this process, None: all cores). `out_dir`: also write the results folder
    (metrics.json, CSVs, figures unless `figures=False`, report.html); the dict then has it
    under `out_dir`. The raw `SweepResult` is under `result`.
    """
    from leonav_runtime.sweep import run as sweep

    _check_run_options(trials, workers)
    scn = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    res = sweep.run_sweep(scn, None, trials=trials, workers=workers, progress=progress, figures=figures)
    if out_dir is not None:
        from leonav_runtime.sweep import report as sweep_report

        sweep_report.write_results(res.scenario, Path(out_dir), res, figures=figures)
    out = sweep_arrays(res)
    out.update({"out_dir": None if out_dir is None else Path(out_dir), "result": res})
    return out


def _columns(rows: list[dict[str, str]]) -> dict[str, np.ndarray]:
    """{column: float array} of CSV rows read by csv.DictReader (an empty cell is NaN)."""
    return {key: np.array([float(r[key]) if r[key] not in ("", None) else math.nan for r in rows], float)
            for key in (rows[0] if rows else {})}


def _csv_rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _read_columns(path: Path) -> dict[str, dict[str, np.ndarray]]:
    """{mode: {column: array}} of a replay CSV (t_s, mode, numeric columns with units)."""
    by_mode: dict[str, list[dict[str, str]]] = {}
    for row in _csv_rows(path):
        by_mode.setdefault(row.pop("mode"), []).append(row)
    return {m: _columns(rows) for m, rows in by_mode.items()}


def run_replay(session: str | Path, *, out_dir: str | Path | None = None, tle: Sequence[str | Path] = (),
               modes: Sequence[str] | None = None, **options: Any) -> dict[str, Any]:
    """Replay a recorded session (`leonav record` / `leonav session synth` folder).

    Returns {"metrics": the metrics.json content, "errors": {mode: {t_s, position_error_m, ...}},
    "trajectory": {mode: {t_s, p_e_m, ..., yaw_deg}}, "out_dir"}. `tle`: element files of the
    capture's day (default: the built-in Walker constellation, right for synthetic sessions);
    `options`: further `replay.ReplayOptions` fields (origin_deg, yaw_deg, gnss_latency_s, ...).
    Without `out_dir` the files go to a temporary folder that is removed.
    """
    from leonav_runtime import replay
    from leonav_runtime.orbits.elements import load_element_files

    opts = replay.ReplayOptions(**({"modes": tuple(modes)} if modes else {}), **options)
    elements = load_element_files([str(p) for p in tle]) if tle else None
    with tempfile.TemporaryDirectory(prefix="leonav-replay-") as tmp:
        folder = Path(out_dir) if out_dir is not None else Path(tmp)
        metrics = replay.replay_session(session, folder, opts, elements=elements)
        return {"metrics": metrics, "errors": _read_columns(folder / "rmse_vs_time.csv"),
                "trajectory": _read_columns(folder / "trajectory.csv"),
                "out_dir": None if out_dir is None else folder}


def run_dataset(description: str | Path, *, until_s: float | None = None, outages: bool = True,
                out_dir: str | Path | None = None) -> dict[str, Any]:
    """Run and score a GNSS/INS dataset (`leonav run`): a description TOML (docs/datasets.md) or
    a shipped name such as `cpet_run3`.

    `until_s`: only the first seconds after the first GNSS fix; `outages`: also the runs with
    fixes removed. Returns {"metrics": the metrics.json content, "errors": the columns of
    errors.csv (`t_s`, `gps_alone_horizontal_m`, `<mode>_horizontal_m`, `<mode>_e_m`, ...,
    `<mode>_yaw_err_deg`, at the reference epochs), "out_dir"}. Without `out_dir` the files go
    to a temporary folder that is removed.
    """
    from leonav_runtime.dataset import load_spec
    from leonav_runtime.dataset.evaluate import run_dataset as _run

    if until_s is not None and not (isinstance(until_s, (int, float)) and math.isfinite(until_s) and until_s > 0):
        raise UserInputError(f"until_s = {until_s!r}: expected seconds > 0")
    spec = load_spec(description)
    with tempfile.TemporaryDirectory(prefix="leonav-run-") as tmp:
        folder = Path(out_dir) if out_dir is not None else Path(tmp)
        metrics = _run(spec, folder, t_end_s=until_s, outages=outages)
        errors = _columns(_csv_rows(folder / "errors.csv"))
        return {"metrics": metrics, "errors": errors, "out_dir": None if out_dir is None else folder}


def run_study(study: str | Path, *, sets: Sequence[str] = (), trials: int | None = None, workers: int | None = 1,
              out_dir: str | Path | None = None, figures: bool = True) -> dict[str, Any]:
    """Run a study (`leonav study`): a shipped name such as `where-is-6-9m` or a TOML path.

    `sets`: `key=value` overrides as `--set` takes them; `trials`: trials per cell and mode
    instead of the file's. Returns {"axes": [{"key", "values"}], "modes", "cells": one dict
    per (cell, mode) with the varied values and `position_rmse_m`, `position_sqrt_pcrb_m`,
    `position_final_rmse_m`, ..., `velocity_*_mps`, `attitude_*_deg`, `nees_mean`}, and per
    mode grid arrays shaped like the axes, e.g. `grid["leo-alpha+imu"]["position_rmse_m"]`.
    Without `out_dir` the files (study.csv/json/png) go to a temporary folder that is removed.
    """
    import dataclasses

    from leonav_runtime.study.run import KINDS, metric_key
    from leonav_runtime.study.run import run_study as _run
    from leonav_runtime.study.spec import load_study

    _check_run_options(trials, workers)
    spec = load_study(study, list(sets))
    if trials is not None:
        spec = dataclasses.replace(spec, trials=int(trials))
    shape = tuple(len(a.values) for a in spec.axes)
    with tempfile.TemporaryDirectory(prefix="leonav-study-") as tmp:
        folder = Path(out_dir) if out_dir is not None else Path(tmp)
        res = _run(spec, folder, workers=workers, progress=False, figures=figures)
    cells, grid = [], {}
    for cell in spec.cells:
        for mode in spec.modes:
            row = res.rows[(cell.index, mode)]
            entry = {"values": dict(cell.values), "mode": mode, "count": cell.count, "nees_mean": row["nees_mean"]}
            for block in _BLOCKS:
                for kind in KINDS:   # the study's own keys: units and sqrt naming as here
                    key = metric_key(block, kind)
                    entry[key] = row[key]
                    grid.setdefault(mode, {}).setdefault(key, np.full(shape, np.nan))[cell.index] = entry[key]
            cells.append(entry)
    return {"name": spec.name, "axes": [{"key": a.key, "values": list(a.values)} for a in spec.axes],
            "modes": list(spec.modes), "trials": spec.trials, "cells": cells, "grid": grid,
            "timing": res.timing, "out_dir": None if out_dir is None else folder}
