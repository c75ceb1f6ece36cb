"""The Python API (`import leonav`): docs/api.md's example runs as written, and the arrays
it returns agree with the sweep's own summaries and files."""
from __future__ import annotations

import csv
import math
import re
from pathlib import Path

import numpy as np
import pytest

import leonav

DOC = Path(__file__).resolve().parents[1] / "docs" / "api.md"


@pytest.mark.slow
def test_docs_example_runs(capsys):
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)
    assert len(blocks) >= 3
    scope: dict = {}
    for code in blocks:
        exec(compile(code, str(DOC), "exec"), scope)  # noqa: S102 (the documented example, verbatim)
    res = scope["res"]
    assert (scope["folder"] / "report.html").is_file() and (scope["folder"] / "metrics.json").is_file()
    assert "leo-alpha+imu" in capsys.readouterr().out
    assert res["position_rmse_m"].shape == (2, 2)
    study = scope["study"]      # sigma_alpha 0.1 vs 1.2 Hz/s: the quieter Doppler-rate ends closer
    assert study["grid"]["leo-alpha+imu"]["position_final_sqrt_pcrb_m"][0] < \
        study["grid"]["leo-alpha+imu"]["position_final_sqrt_pcrb_m"][1]


def test_study_arrays_are_the_study_files(tmp_path):
    """run_study's cells and grids hold the numbers of study.csv, in its units (m, m/s, deg)."""
    spec = tmp_path / "s.toml"
    spec.write_text('name = "s"\nscenario = "paper"\nmodes = ["gps+imu", "leo-alpha+imu"]\ncount = 5\n'
                    'trials = 2\n[set]\n"time.duration_s" = 2.0\n[[vary]]\nkey = "starlink.rate_hz"\n'
                    'values = [1, 2]\n')
    res = leonav.run_study(spec, out_dir=tmp_path / "out", figures=False)
    with open(tmp_path / "out" / "study.csv") as fh:
        rows = {(r["mode"], float(r["starlink.rate_hz"])): r for r in csv.DictReader(fh)}
    assert len(res["cells"]) == len(rows) == 4
    for cell in res["cells"]:
        row = rows[(cell["mode"], float(cell["values"]["starlink.rate_hz"]))]
        assert cell["position_rmse_m"] == pytest.approx(float(row["position_rmse_m"]))
        assert cell["attitude_final_sqrt_pcrb_deg"] == pytest.approx(float(row["attitude_final_sqrt_pcrb_deg"]))
        k = res["axes"][0]["values"].index(cell["values"]["starlink.rate_hz"])
        assert res["grid"][cell["mode"]]["velocity_sqrt_pcrb_mps"][k] == cell["velocity_sqrt_pcrb_mps"]


def test_arrays_match_the_summaries_and_the_csv(tmp_path):
    import tomli_w

    raw = leonav.load_scenario("paper").raw
    raw["time"]["duration_s"] = 2.0
    (tmp_path / "short.toml").write_text(tomli_w.dumps(raw))
    scn = leonav.load_scenario(tmp_path / "short.toml", modes=["gps+imu", "leo-alpha+imu"], counts=[5, 10])
    res = leonav.run_sweep(scn, trials=2, out_dir=tmp_path / "out", figures=False)
    raw = res["result"]
    for i, mode in enumerate(res["modes"]):
        for j, count in enumerate(res["counts"]):
            s = raw.summaries[(mode, count)]
            assert res["position_rmse_m"][i, j] == s["position"]["rmse"]
            assert res["attitude_rmse_deg"][i, j] == pytest.approx(math.degrees(s["attitude"]["rmse"]))
            assert res["velocity_final_sqrt_pcrb_mps"][i, j] == s["velocity"]["final_pcrb"]
    with open(tmp_path / "out" / "rmse.csv") as fh:
        rows = {(r["mode"], int(r["count"])): r for r in csv.DictReader(fh)}
    for row in res["table"]:
        assert float(rows[(row["mode"], row["count"])]["att_rmse_deg"]) == pytest.approx(row["attitude_rmse_deg"])
    assert np.all(np.diff(res["t_s"]) > 0) and res["curves"][("gps+imu", 5)]["position_rmse_m"].size == res["t_s"].size


def test_bad_changes_are_user_errors():
    from leonav_runtime.common.errors import UserInputError

    # named as the Python arguments they are, not as command-line options
    with pytest.raises(UserInputError, match=r"^modes: 'warp': unknown word"):
        leonav.load_scenario("paper", modes=["warp"])
    with pytest.raises(UserInputError, match=r"^seed=-1: expected"):
        leonav.load_scenario("paper", seed=-1)
    assert leonav.__version__ and "run_replay" in leonav.__all__


def test_run_replay_in_memory_leaves_no_folder(tmp_path, monkeypatch):
    from leonav_runtime.cli import main

    session = tmp_path / "s"
    assert main(["session", "synth", str(session), "--seconds", "3", "--sdr-rate", "200e3"]) == 0
    monkeypatch.chdir(tmp_path)
    before = set(tmp_path.iterdir())
    out = leonav.run_replay(session, modes=["fix+imu"])
    assert set(tmp_path.iterdir()) == before and out["out_dir"] is None
    err = out["errors"]["fix+imu"]
    assert err["t_s"].size > 10 and np.all(np.isfinite(err["position_error_m"]))
    rms = float(np.sqrt(np.mean(err["position_error_m"] ** 2)))
    assert rms == pytest.approx(out["metrics"]["modes"]["fix+imu"]["rmse_position_m"], rel=1e-6)
    assert set(out["trajectory"]["fix+imu"]) >= {"t_s", "p_e_m", "yaw_deg"}


@pytest.mark.parametrize("call", [lambda: leonav.run_study("where-is-6-9m", trials=0),
                                  lambda: leonav.run_study("where-is-6-9m", trials=100001),
                                  lambda: leonav.run_study("where-is-6-9m", trials=2.5),
                                  lambda: leonav.run_sweep("paper", trials=0),
                                  lambda: leonav.run_sweep("paper", trials=1, workers=0)])
def test_bad_run_options_are_user_errors_before_any_work(call):
    from leonav_runtime.common.errors import UserInputError

    with pytest.raises(UserInputError, match=r"(trials|workers) = "):
        call()


def test_docs_table_lists_every_entry_point_and_built_in():
    from leonav_runtime.scenarios import load as scenario_module

    text = DOC.read_text()
    table = re.search(r"\| call \| returns \|\n((?:\|.*\|\n)+)", text).group(1)   # contiguous rows only
    for name in ("load_scenario", "run_sweep", "run_replay", "run_study"):
        assert f"`leonav.{name}(" in table, name
    built_ins = sorted(p.stem for p in Path(scenario_module.__file__).parent.glob("*.toml"))
    assert built_ins and all(f"`{b}`" in table for b in built_ins)
    assert all(f"`{b}`" in leonav.load_scenario.__doc__ for b in built_ins)
    readme = (DOC.parents[1] / "README.md").read_text()
    python_bullet = re.search(r"- \*\*Python\*\*:.*?(?=\n- |\n\n)", readme, flags=re.S).group(0)
    assert "run_study" in python_bullet


def test_run_dataset_in_memory_scores_the_drive_and_leaves_no_folder(tmp_path, monkeypatch):
    from leonav_runtime.dataset.synthetic import DriveConfig, write_drive

    drive = write_drive(tmp_path / "drive", DriveConfig(seconds=30.0))
    monkeypatch.chdir(tmp_path)
    before = set(tmp_path.iterdir())
    run = leonav.run_dataset(drive.toml, outages=False)
    assert set(tmp_path.iterdir()) == before and run["out_dir"] is None
    e, m = run["errors"], run["metrics"]
    assert e["t_s"].size == m["reference_epochs"] and np.all(np.diff(e["t_s"]) > 0)
    for mode, s in m["modes"].items():   # the returned columns are the metrics' own errors
        assert np.sqrt(np.nanmean(e[f"{mode}_horizontal_m"] ** 2)) == pytest.approx(s["rmse_horizontal_m"], rel=1e-3)
    from leonav_runtime.common.errors import UserInputError

    with pytest.raises(UserInputError, match="until_s"):
        leonav.run_dataset(drive.toml, until_s=-1.0)
