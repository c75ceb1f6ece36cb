"""Monte Carlo sweep: executor independence, efficiency vs the PCRB, consistency, outages, CLI."""
from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from leonav_runtime.cli import main
from leonav_runtime.scenarios.load import MODES, load_scenario, scenario_from_dict
from leonav_runtime.sweep.run import outage_end_error, run_sweep

try:
    import tomllib
except ImportError:  # Python 3.10
    import tomli as tomllib


def _paper(**changes):
    raw = copy.deepcopy(load_scenario("paper").raw)
    for dotted, value in changes.items():
        section, key = dotted.split("__")
        raw.setdefault(section, {})[key] = value
    return scenario_from_dict(raw, source="<paper test>")


def _positions(res):
    """Everything the sweep reports per point that depends on the trials and the bound."""
    return {k: (s["position"]["rmse"], s["velocity"]["rmse"], s["attitude"]["rmse"], s["position"]["pcrb"],
                s["nees"]["mean"], tuple(sorted((kind, v["mean"]) for kind, v in s["nis"].items())), s["gated"])
            for k, s in res.summaries.items()}


def test_results_do_not_depend_on_the_executor(tmp_path):
    distributed = pytest.importorskip("distributed")
    scn = _paper(time__duration_s=3.0, starlink__counts=[5, 10], monte_carlo__modes=["gps+imu", "leo-alpha+imu"])
    inline = run_sweep(scn, tmp_path / "a", trials=12, workers=1, progress=False, figures=False)
    pooled = run_sweep(scn, tmp_path / "b", trials=12, workers=2, progress=False, figures=False)
    with distributed.LocalCluster(host="127.0.0.1", n_workers=1, threads_per_worker=2, processes=False,
                                  protocol="tcp://", dashboard_address=None) as cluster:
        on_dask = run_sweep(scn, tmp_path / "c", trials=12, dask_address=cluster.scheduler_address,
                            progress=False, figures=False)
    assert _positions(inline) == _positions(pooled) == _positions(on_dask)
    # GPS+IMU does not use Starlink: one run reported at every count
    assert inline.summaries[("gps+imu", 5)] is inline.summaries[("gps+imu", 10)]


@pytest.fixture(scope="module")
def sweep45(tmp_path_factory):
    scn = _paper(starlink__counts=[45])
    return scn, run_sweep(scn, tmp_path_factory.mktemp("s45"), trials=100, workers=2, progress=False,
                          figures=False)


@pytest.mark.parametrize("mode", MODES)
def test_filter_is_efficient_at_45_satellites(sweep45, mode):
    scn, res = sweep45
    s = res.summaries[(mode, 45)]
    assert s["position"]["ratio"] <= 1.2, s["position"]
    assert s["velocity"]["ratio"] <= 1.2, s["velocity"]


@pytest.mark.parametrize("mode", MODES)
def test_filter_is_consistent_nees_and_nis_in_their_bands(sweep45, mode):
    scn, res = sweep45
    s = res.summaries[(mode, 45)]
    lo, hi = s["nees"]["band95"]
    assert lo <= s["nees"]["mean"] <= hi, s["nees"]
    for kind, nis in s["nis"].items():
        lo1, hi1 = nis["band95"]
        assert lo1 <= nis["mean"] <= hi1, (kind, nis)


def test_paper_findings_on_position(sweep45):
    scn, res = sweep45
    pos = {m: res.summaries[(m, 45)]["position"]["rmse"] for m in MODES}
    assert 1.0 <= pos["gps+imu"] <= 2.0 and pos["gps+leo-alpha+imu"] <= pos["gps+imu"]
    assert pos["leo-ofdm+imu"] < pos["leo-alpha+imu"]
    assert pos["leo-alpha+ofdm+imu"] <= min(pos["leo-ofdm+imu"], pos["leo-alpha+imu"])


def test_leo_alpha_keeps_the_error_bounded_through_a_gps_outage(tmp_path):
    raw = copy.deepcopy(load_scenario("maritime-outage").raw)
    raw["time"]["duration_s"] = 100.0
    raw["trajectory"]["maneuvers"] = [[30.0, 0.0, 0.0], [30.0, 0.0, 3.0], [40.0, 0.0, -1.0]]
    raw["gps"]["outages_s"] = [[30.0, 90.0]]
    raw["starlink"]["counts"] = [45]
    raw["monte_carlo"]["modes"] = ["gps+imu", "gps+leo-alpha+imu"]
    scn = scenario_from_dict(raw, source="<maritime test>")
    res = run_sweep(scn, tmp_path, trials=6, workers=2, progress=False, figures=False)
    end = {m: outage_end_error(res.summaries[(m, 45)], 90.0, res.t_eval) for m in scn.modes}
    before = {m: outage_end_error(res.summaries[(m, 45)], 30.0, res.t_eval) for m in scn.modes}
    assert end["gps+imu"] > 3 * before["gps+imu"]           # inertial drift while GPS is denied
    assert end["gps+leo-alpha+imu"] < 0.7 * end["gps+imu"]
    assert any("outage" in f["finding"] and f["holds"] and f["kind"] == "scenario" for f in res.findings)


def test_sweep_cli_writes_the_results_folder(tmp_path, capsys):
    src = load_scenario("paper").source
    raw = tomllib.loads(open(src).read())
    raw["time"]["duration_s"] = 2.0
    raw["starlink"]["counts"] = [5, 10]
    raw["monte_carlo"]["modes"] = ["leo-alpha+ofdm+imu", "gps+imu"]  # not alphabetical: the order is kept
    body = "\n".join(
        f"[{sec}]\n" + "\n".join(f"{k} = {json.dumps(v)}" for k, v in vals.items())
        if isinstance(vals, dict) else f"{sec} = {json.dumps(vals)}"
        for sec, vals in sorted(raw.items(), key=lambda kv: isinstance(kv[1], dict)))
    path = tmp_path / "tiny.toml"
    path.write_text(body + "\n")
    out = tmp_path / "out"
    assert main(["sweep", str(path), "--trials", "2", "--workers", "1", "--no-progress", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "position RMSE / sqrt(PCRB)" in text and "leo-alpha+ofdm+imu" in text
    for name in ("metrics.json", "rmse.csv", "rmse_vs_time.csv", "config.toml", "rmse_vs_count.png",
                 "rmse_vs_time.png", "trajectories.png", "visibility.png"):
        assert (out / name).stat().st_size > 0, name
    metrics = json.loads((out / "metrics.json").read_text())
    # console table, metrics.json and report.html list the modes in the scenario's order
    assert [(r["mode"], r["count"]) for r in metrics["results"]] == [
        (m, c) for m in ("leo-alpha+ofdm+imu", "gps+imu") for c in (5, 10)]
    assert text.index("\nleo-alpha+ofdm+imu ") < text.index("\ngps+imu ")
    html = (out / "report.html").read_text()
    assert html.index("<td>leo-alpha+ofdm+imu</td>") < html.index("<td>gps+imu</td>")
    assert all(np.isfinite(r["position"]["rmse"]) for r in metrics["results"])


def test_sweep_cli_reports_bad_scenarios_with_field_and_value(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text('[time]\nepoch = "2026-02-23T12:00:00Z"\nduration_s = -5.0\n')
    assert main(["sweep", str(path), "--no-progress", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "[time] duration_s = -5.0: expected s in" in err


def test_outage_end_error_reads_the_last_epoch_when_the_outage_reaches_the_end():
    t = np.arange(0.0, 20.05, 0.1)
    summary = {"position": {"rmse_t": np.arange(t.size, dtype=float)}}
    assert outage_end_error(summary, 10.0, t) == 99.0                 # GPS back at 10 s: the epoch before
    assert outage_end_error(summary, 20.0, t) == float(t.size - 1)    # lost to the end: the final epoch


@pytest.mark.slow
def test_paper_findings_only_for_a_scenario_that_declares_itself_the_papers(tmp_path):
    """maritime-outage (like a user's own scenario) prints its own checks, not the paper's verdicts."""
    from leonav_runtime.scenarios.load import load_scenario
    from leonav_runtime.sweep.run import run_sweep, summary_table

    from leonav_runtime.scenarios.overrides import apply_overrides

    paper, maritime = load_scenario("paper"), load_scenario("maritime-outage")
    assert paper.raw["monte_carlo"]["paper_findings"] and not maritime.raw["monte_carlo"].get("paper_findings")
    # the two modes its outage check compares, at one count, in memory: what the verdicts depend on
    maritime, _ = apply_overrides(maritime, modes=["gps+imu", "gps+leo-alpha+imu"], counts=[45])
    res = run_sweep(maritime, None, trials=2, workers=1, progress=False)
    assert res.findings and {f["kind"] for f in res.findings} == {"scenario"}
    assert "the paper's findings" not in summary_table(maritime, res)


def test_a_block_task_gives_each_trial_what_it_gives_alone(monkeypatch):
    """run_block (the block's records at once, one filter object per block, errors and NEES for the
    whole block; a long run in smaller blocks) equals run_trial trial by trial, bit for bit; its
    CPU covers its C loops."""
    from pathlib import Path

    from leonav_runtime.sweep import montecarlo as mc

    scn = _paper(time__duration_s=3.0, starlink__counts=[5, 10])
    for mode, count, samples in (("gps+leo-alpha+imu", 10, mc.BLOCK_SAMPLES), ("leo-alpha+ofdm+imu", 5, 2 * 301)):
        monkeypatch.setattr(mc, "BLOCK_SAMPLES", samples)   # 2 x 301 IMU samples: blocks of 2 trials
        block = mc.run_block((scn.raw, scn.source, str(Path(scn.source).parent), mode, count, [0, 4, 9]))
        assert [r.index for r in block.results] == [0, 4, 9] and block.pcrb is not None
        for r in block.results:
            alone = mc.run_trial(scn, mode, count, r.index)
            assert r.err.tobytes() == alone.err.tobytes() and r.nees.tobytes() == alone.nees.tobytes()
            assert (r.nis_sum, r.nis_count, r.gated, r.failed) == (alone.nis_sum, alone.nis_count, alone.gated,
                                                                   alone.failed)
            assert (r.p_est is None) == (r.index != 0)
        assert np.array_equal(block.p_est_trial0, mc.run_trial(scn, mode, count, 0).p_est)
        assert 0 < block.c_seconds <= block.seconds
    # realism switches: the block takes the road per trial (per-trial R and parameters)
    from tests.conftest import short_paper_scenario

    scn = short_paper_scenario(3.0, [10], "<block realism>",
                               ephemeris_error={"enabled": True, "compensate": "consider"},
                               imu_errors={"enabled": True, "process_noise_inflation": 2.0})
    block = mc.run_block((scn.raw, scn.source, str(Path(scn.source).parent), "leo-alpha+imu", 10, [1, 2]))
    for r in block.results:
        alone = mc.run_trial(scn, "leo-alpha+imu", 10, r.index)
        assert r.err.tobytes() == alone.err.tobytes() and r.nis_sum == alone.nis_sum


def test_sweep_timing_is_cpu_against_its_c_floor(tmp_path):
    scn = _paper(time__duration_s=3.0, starlink__counts=[5], monte_carlo__modes=["gps+imu"])
    t = run_sweep(scn, None, trials=20, workers=1, progress=False, figures=False).timing
    assert t["trials_run"] == 20 and t["imu_steps_per_trial"] == 300
    assert t["floor_cpu_s"] == pytest.approx(20 * 300 * t["c_us_per_imu_step"] * 1e-6)
    # inline: this process ran every trial, so its CPU holds the trials' (thread) CPU and the floor
    assert t["floor_cpu_s"] < 1e-3 * t["trial_cpu_ms"] * 20 <= t["process_cpu_s"] + 0.005
    assert t["total_cpu_s"] == pytest.approx(t["process_cpu_s"] + t["workers_cpu_s"])
    assert t["cpu_over_floor"] == pytest.approx(t["total_cpu_s"] / t["floor_cpu_s"]) and t["cpu_over_floor"] > 1
