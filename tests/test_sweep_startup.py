"""A paper sweep loads only the SciPy it uses (issue 25): `scipy.special` for the NEES / NIS
bands, not `scipy.signal` (0.5-1.4 s to import here, for a Gauss-Markov truth the paper has
not), `scipy.stats` nor `scipy.integrate` (a moving profile's position integral); without
figures, no matplotlib. Checked in a fresh interpreter after a real sweep (sys.modules at the
end); a scenario that moves does load scipy.integrate, so the check can see it."""
from __future__ import annotations

from pathlib import Path

from tests.conftest import modules_after_main

NOT_FOR_THE_PAPER = ("scipy.signal", "scipy.stats", "scipy.integrate", "scipy.optimize", "scipy.interpolate")


def _modules_after(argv: list[str], tmp_path: Path) -> set[str]:
    rc, modules = modules_after_main(argv, tmp_path, timeout_s=600)
    assert rc == 0
    return modules


def _sweep(tmp_path: Path, *extra: str) -> list[str]:
    return ["sweep", "--trials", "2", "--counts", "5", "--modes", "gps+imu,leo-doppler+alpha+imu",
            "--workers", "1", "--no-progress", "--out", str(tmp_path / "out"), *extra]


def test_a_paper_sweep_imports_no_scipy_it_does_not_use(tmp_path):
    modules = _modules_after(_sweep(tmp_path), tmp_path)
    assert {"leonav_runtime.sweep.montecarlo", "leonav_runtime.simulation.sensor_errors", "scipy.special"} <= modules
    assert sorted(m for m in modules if m.startswith(NOT_FOR_THE_PAPER)) == []
    assert (tmp_path / "out" / "rmse.csv").is_file()


def test_a_sweep_without_figures_imports_no_matplotlib(tmp_path):
    """--no-figures: matplotlib (~0.2 s of CPU to import) is not loaded; with figures it is."""
    modules = _modules_after(_sweep(tmp_path, "--no-figures"), tmp_path)
    assert sorted(m for m in modules if m.split(".")[0] == "matplotlib") == []
    assert (tmp_path / "out" / "report.html").is_file() and not list((tmp_path / "out").glob("*.png"))
    assert "matplotlib" in _modules_after(_sweep(tmp_path), tmp_path)


def test_a_moving_scenario_loads_the_position_integral(tmp_path):
    modules = _modules_after(_sweep(tmp_path, "--set", "trajectory.kind=maneuvers"), tmp_path)
    assert "scipy.integrate" in modules


def test_the_nees_and_nis_bands_are_scipy_stats_chi2_quantiles():
    """The bands' formula (without importing scipy.stats) against scipy.stats.chi2.ppf itself."""
    import numpy as np
    from scipy import stats

    from leonav_runtime.sweep.montecarlo import _chi2_quantiles
    for dof in (1, 2, 9, 17, 900, 41_400, 160_000, 1_234_567):
        np.testing.assert_array_equal(_chi2_quantiles(dof), stats.chi2.ppf([0.025, 0.975], dof), err_msg=str(dof))
