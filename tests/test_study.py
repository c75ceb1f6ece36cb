"""Studies: grid expansion, validation naming the key, a tiny study end to end (CLI included)."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from leonav_runtime.cli import main
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.study.run import run_study
from leonav_runtime.study.spec import Axis, expand_grid, load_study, parse_set, study_from_dict
from leonav_runtime.sweep.run import run_sweep

TINY = {   # 2 s static run, 5 satellites: a cell prepares in a fraction of a second
    "scenario": "paper", "modes": ["leo-alpha+imu"], "count": 5, "trials": 3,
    "set": {"time.duration_s": 2.0, "monte_carlo.seed": 11},
}


def _study(tmp_path, vary, **extra):
    return study_from_dict({**TINY, **extra, "vary": vary}, str(tmp_path / "s.toml"), tmp_path)


def test_grid_is_every_combination_first_axis_slowest():
    axes = [Axis("a.x", (1, 2, 3), "x"), Axis("b.y", ("p", "q"), "y")]
    grid = expand_grid(axes)
    assert [idx for idx, _ in grid] == [(0, 0), (0, 1), (1, 0), (1, 1), (2, 0), (2, 1)]
    assert grid[3][1] == {"a.x": 2, "b.y": "q"}


def test_cells_carry_the_varied_and_fixed_values_in_si(tmp_path):
    s = _study(tmp_path, [{"key": "starlink.elevation_mask_deg", "values": [20.0, 28.0]},
                          {"key": "filter.initial_position_sigma_m", "values": [3, 10]}])
    assert len(s.cells) == 4 and s.modes == ["leo-alpha+imu"]
    c = s.cells[1]
    assert c.values == {"starlink.elevation_mask_deg": 20.0, "filter.initial_position_sigma_m": 10}
    assert c.scenario.starlink["elevation_mask_rad"] == pytest.approx(0.3490658503988659)
    assert c.scenario.filter["initial_position_sigma_m"] == 10.0
    assert c.scenario.duration_s == 2.0 and c.scenario.seed == 11 and c.count == 5
    # counts as the varied field: each cell runs its own count
    s = _study(tmp_path, [{"key": "starlink.counts", "values": [5, 8]}])
    assert [c.count for c in s.cells] == [5, 8]


@pytest.mark.parametrize("vary, fragment", [
    ([{"key": "starlink.doppler_rate_sigma", "values": [1.0]}], "starlink.doppler_rate_sigma_hz_s"),
    ([{"key": "starlink.doppler_rate_sigma_hz_s", "values": [-1.0]}], "doppler_rate_sigma_hz_s = -1.0"),
    ([{"key": "imu.profile", "values": ["navigation"]}], "profile = 'navigation': expected one of"),
    ([{"key": "starlink.rate_hz", "values": [3.0]}], "rate_hz = 3: measurements are tagged on IMU samples"),
    ([{"key": "filter.gate_nis", "values": []}], "filter.gate_nis: values"),
    ([], "one or two [[vary]]"),
    ([{"key": "time.duration_s", "values": [1.0]}], "also fixed by [set]"),
    ([{"key": "starlink.rate_hz", "values": [1, 1.0]}], "1.0 repeats"),
    ([{"key": "starlink.doppler_rate_sigma_hz_s", "values": [0.1, 0.3, 0.10]}], "0.1 repeats"),
    ([{"key": "starlink.rate_hz", "values": [1, 2], "label": 5}], "label = 5: expected a string"),
    ([{"key": "starlink.counts", "values": [[5, 10], [20]]}], "expected single counts"),
])
def test_bad_studies_name_the_key(tmp_path, vary, fragment):
    with pytest.raises(UserInputError) as exc:
        _study(tmp_path, vary)
    assert fragment in str(exc.value)
    assert "s.toml" in str(exc.value)


def test_set_values_parse_as_toml_and_unknown_keys_are_named():
    assert parse_set("starlink.doppler_rate_sigma_hz_s=0.3") == ("starlink.doppler_rate_sigma_hz_s", 0.3)
    assert parse_set("imu.profile=wt901") == ("imu.profile", "wt901")
    assert parse_set("starlink.counts=[5, 10]") == ("starlink.counts", [5, 10])
    with pytest.raises(UserInputError, match="--set 'filter.prior=3'.*unknown scenario key 'filter.prior'"):
        parse_set("filter.prior=3")
    with pytest.raises(UserInputError, match="expected key=value"):
        parse_set("imu.profile")


def test_tiny_study_matches_the_sweep_and_the_bound_orders_by_noise(tmp_path):
    study = _study(tmp_path, [{"key": "starlink.doppler_rate_sigma_hz_s", "values": [0.1, 1.2]}])
    res = run_study(study, tmp_path / "out", workers=1, progress=False, figures=False)
    lo, hi = (res.rows[(c.index, "leo-alpha+imu")] for c in study.cells)
    # the bound is deterministic: 12x less alpha noise carries more position information
    assert lo["position_sqrt_pcrb_m"] < hi["position_sqrt_pcrb_m"] and lo["position_final_sqrt_pcrb_m"] < hi["position_final_sqrt_pcrb_m"]
    # a cell is the sweep of the same scenario: same seeds, same numbers
    sweep = run_sweep(study.cells[1].scenario, tmp_path / "sweep", trials=3, workers=1, progress=False,
                      figures=False)
    s = sweep.summaries[("leo-alpha+imu", 5)]["position"]
    assert (hi["position_rmse_m"], hi["position_final_rmse_m"], hi["position_sqrt_pcrb_m"]) == \
        (s["rmse"], s["final_rmse"], s["pcrb"])
    rows = list(csv.DictReader(open(tmp_path / "out" / "study.csv")))
    assert [float(r["starlink.doppler_rate_sigma_hz_s"]) for r in rows] == [0.1, 1.2]
    assert float(rows[1]["position_final_rmse_m"]) == pytest.approx(hi["position_final_rmse_m"])


def test_study_cli_writes_table_json_figure(tmp_path, capsys):
    path = tmp_path / "one.toml"
    path.write_text('name = "one"\nscenario = "paper"\nmodes = ["leo-alpha+imu"]\ncount = 5\ntrials = 2\n'
                    '[set]\n"time.duration_s" = 2.0\n'
                    '[[vary]]\nkey = "filter.initial_position_sigma_m"\nvalues = [3.0, 30.0]\n')
    out = tmp_path / "out"
    assert main(["study", str(path), "--out", str(out), "--workers", "1", "--no-progress", "--trials", "1",
                 "--set", "starlink.elevation_mask_deg=25"]) == 0
    meta = json.loads((out / "study.json").read_text())
    assert meta["set"]["starlink.elevation_mask_deg"] == 25 and len(meta["cells"]) == 2
    assert meta["cells"][0]["position_sqrt_pcrb_m"] < meta["cells"][1]["position_sqrt_pcrb_m"]   # tighter prior, lower bound
    assert (out / "study.png").stat().st_size > 10_000
    again = load_study(out / "study.toml")      # the written study repeats the run, --set included
    assert again.trials == 1 and again.sets["starlink.elevation_mask_deg"] == 25
    text = capsys.readouterr().out
    table = [line for line in text.splitlines() if "leo-alpha+imu" in line or "filter.initial_position_sigma_m" in line]
    assert len(table) == 3 and "mode" in table[0]                  # header (the axis key) and one row per cell
    assert [line.split()[0] for line in table[1:]] == ["3.0", "30.0"]
    # columns straight whatever the value widths: every number column ends where its header ends
    header = table[0]
    for j, name in enumerate(["RMSE", "sqrt(PCRB)"]):
        end = header.index(f" {name} ") + len(name) + 1
        assert all(line[:end].endswith(line.split()[3 + j]) for line in table[1:]), (name, table)
    assert main(["study", str(path), "--out", str(out), "--set", "filter.bogus=1"]) == 2
    assert "unknown scenario key 'filter.bogus'" in capsys.readouterr().err


def test_shipped_studies_load():
    for name in sorted(p.stem for p in (Path(__file__).parents[1] / "leonav_runtime/study/studies").glob("*.toml")):
        study = load_study(name)
        assert study.cells and study.trials >= 1


def test_study_help_names_every_shipped_study(capsys):
    """The help's list of shipped studies is the studies folder (it was a hand-kept list that
    missed the two added after it)."""
    with pytest.raises(SystemExit):
        main(["study", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    names = sorted(p.stem for p in (Path(__file__).parents[1] / "leonav_runtime/study/studies").glob("*.toml"))
    assert "passive-phase-front-end" in names
    for name in names:   # argparse may break a name at its hyphens
        assert name in text.replace("- ", "-"), name


def test_study_outputs_carry_units_and_a_report_and_the_paper_contours(tmp_path):
    import re

    from matplotlib.contour import ContourSet

    from leonav_runtime.common import plot_style as ps
    from leonav_runtime.study import plots

    study = _study(tmp_path, [{"key": "filter.initial_position_sigma_m", "values": [3.0, 30.0]},
                              {"key": "starlink.doppler_rate_sigma_hz_s", "values": [0.1, 1.2]}],
                   modes=["gps+imu", "leo-alpha+imu"], trials=2)
    out = tmp_path / "out"
    res = run_study(study, out, workers=1, progress=False, figures=True)
    header = next(csv.reader(open(out / "study.csv")))
    for key in ("position_rmse_m", "position_sqrt_pcrb_m", "position_final_sqrt_pcrb_m", "velocity_rmse_mps",
                "attitude_rmse_deg", "attitude_final_sqrt_pcrb_deg"):
        assert key in header
    metric = [h for h in header if re.match(r"(position|velocity|attitude)_", h)]
    assert len(metric) == 12 and all(h.endswith(("_m", "_mps", "_deg")) and "pcrb" not in h.replace("sqrt_pcrb", "")
                                      for h in metric)
    meta = json.loads((out / "study.json").read_text())
    assert set(metric) <= set(meta["cells"][0])
    page = (out / "report.html").read_text()
    from tests.test_report_html import external_references

    assert external_references(page) == [] and page.count("data:image/png;base64,") == 1
    assert "pos sqrt(PCRB) [m]" in page and "leonav version" in page
    assert f"{meta['cells'][0]['position_rmse_m']:.4g}" in page
    # the figure: 6-9 m contours only on LEO(alpha)+IMU's position maps, plain NEES colour-bar ticks
    assert plots.paper_band(study, "leo-alpha+imu") == (6.0, 9.0) and plots.paper_band(study, "gps+imu") is None
    fake = {k: {**row, "position_rmse_m": v, "position_final_rmse_m": v}   # a grid that crosses 6 and 9 m
            for (k, row), v in zip(res.rows.items(), [4.0, 7.0, 8.0, 12.0] * 2)}
    fig = plots._two_fields(ps.pyplot(), study, fake)
    fig.canvas.draw()
    axes = fig.axes
    has_contour = [any(isinstance(c, ContourSet) for c in ax.collections) for ax in axes[:6]]
    assert has_contour == [False, False, False, True, True, False]         # rows: gps+imu, leo-alpha+imu
    nees_bar = [ax for ax in axes if ax.get_ylabel() == "NEES [-]"][0]
    labels = [t.get_text() for t in nees_bar.get_yticklabels() if t.get_text()]
    assert labels and all(re.fullmatch(r"[0-9.]+", t) for t in labels)


def test_description_must_be_text_and_bools_are_not_numbers(tmp_path):
    with pytest.raises(UserInputError, match="description = 3: expected a string"):
        _study(tmp_path, [{"key": "starlink.rate_hz", "values": [1]}], description=3)
    s = _study(tmp_path, [{"key": "imu_errors.enabled", "values": [False, True]}])
    assert [c.values["imu_errors.enabled"] for c in s.cells] == [False, True]
