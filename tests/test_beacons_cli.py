"""`leonav beacons` end to end: --simulate writes every output; bad input exits 2 with a reason."""
from __future__ import annotations

import csv
import json

import pytest

from leonav_runtime.cli import main
from tests.conftest import shared_file


def test_simulate_writes_all_outputs(tmp_path, capsys):
    tle = shared_file("tle/starlink_2026-02-23.txt")
    out = tmp_path / "out"
    rc = main(["beacons", str(tmp_path / "sim.cu8"), "--simulate", "--tle", str(tle), "--duration", "5",
               "--sim-rate", "500e3", "--band", "500e3", "--n-sats", "5", "--cn0", "38",
               "--start", "2026-02-23T06:00:00Z", "--out", str(out)])
    assert rc == 0
    for name in ("associations.csv", "doppler_rate_measurements.csv", "doppler_rate_measurements.columns.txt",
                 "waterfall.png", "summary.json", "synthetic_truth.json"):
        assert (out / name).stat().st_size > 0, name
    truth = set(json.loads((out / "synthetic_truth.json").read_text())["norad_ids"])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["counts"]["associated"] == 5 and summary["counts"]["ridges"] == 5
    rows = list(csv.DictReader((out / "doppler_rate_measurements.csv").open()))
    assert {int(r["norad_id"]) for r in rows} == truth
    assert all(abs(float(r["rate_residual_hz_s"])) < 5 and float(r["sigma_hz_s"]) > 0 for r in rows)
    assert "associated 5" in capsys.readouterr().out


def test_raw_capture_without_start_is_a_clear_error(tmp_path, capsys):
    tle = shared_file("tle/starlink_2026-02-23.txt")
    cap = tmp_path / "x.cu8"
    cap.write_bytes(bytes(4096))
    rc = main(["beacons", str(cap), "--tle", str(tle), "--sample-rate", "1e6", "--center-freq", "1.575e9",
               "--out", str(tmp_path / "o")])
    assert rc == 2
    assert "start time unknown" in capsys.readouterr().err


def test_no_tle_is_a_clear_error(tmp_path, capsys):
    cap = tmp_path / "x.cu8"
    cap.write_bytes(bytes(4096))
    assert main(["beacons", str(cap), "--out", str(tmp_path / "o")]) == 2
    assert "--tle" in capsys.readouterr().err


def _simulated_capture(tmp_path, tle) -> list[str]:
    """A short synthetic capture (5 s at 500 kS/s, 3 satellites) written once; the CLI args to process it."""
    cap = tmp_path / "sim.cu8"
    assert main(["beacons", str(cap), "--simulate", "--sim-format", "cu8", "--tle", str(tle), "--duration", "5",
                 "--sim-rate", "500e3", "--band", "500e3", "--n-sats", "3", "--cn0", "38",
                 "--start", "2026-02-23T06:00:00Z", "--out", str(tmp_path / "sim")]) == 0
    return ["beacons", str(cap), "--tle", str(tle), "--band", "500e3"]


def test_no_figures_writes_the_same_numbers_and_no_png(tmp_path, capsys):
    args = _simulated_capture(tmp_path, shared_file("tle/starlink_2026-02-23.txt"))
    assert main(args + ["--out", str(tmp_path / "fig")]) == 0
    assert main(args + ["--no-figures", "--out", str(tmp_path / "nofig")]) == 0
    fig, nofig = tmp_path / "fig", tmp_path / "nofig"
    assert (fig / "waterfall.png").stat().st_size > 0
    assert not list(nofig.glob("*.png"))
    for name in ("associations.csv", "doppler_rate_measurements.csv", "doppler_rate_measurements.columns.txt"):
        assert (fig / name).read_bytes() == (nofig / name).read_bytes(), name
    s_fig, s_nofig = (json.loads((d / "summary.json").read_text()) for d in (fig, nofig))
    s_fig.pop("provenance"), s_nofig.pop("provenance")  # the command lines differ
    assert s_fig == s_nofig and s_fig["counts"]["associated"] == 3


_MODULES_AFTER = """
import sys
from leonav_runtime.cli import main
rc = main(sys.argv[1:])
print(rc, "matplotlib" in sys.modules, "casadi" in sys.modules,
      any(m in sys.modules for m in ("scipy.interpolate", "scipy.optimize", "scipy.linalg")),
      ",".join(sorted(m for m in sys.modules if m.startswith("scipy"))) or "-")
"""


@pytest.mark.slow
def test_the_beacons_path_imports_matplotlib_only_to_draw_the_figure(tmp_path):
    """In a fresh interpreter: the whole command with --no-figures never imports matplotlib (nor
    casadi, nor SciPy's interpolation, optimization or linear algebra: the spline and the
    assignment are the runtime's own; SciPy's compiled FFT extension is the one SciPy module
    loaded, without any SciPy package); the same command drawing the figure does import
    matplotlib, so the check can see it."""
    import subprocess
    import sys

    args = _simulated_capture(tmp_path, shared_file("tle/starlink_2026-02-23.txt"))
    seen = {}
    for flag in ("--no-figures", None):
        argv = args + ["--out", str(tmp_path / f"o{flag}")] + ([flag] if flag else [])
        out = subprocess.run([sys.executable, "-c", _MODULES_AFTER, *argv], capture_output=True, text=True,
                             check=True).stdout.split()
        seen[flag] = out[-5:]
    assert seen["--no-figures"] == ["0", "False", "False", "False", "scipy.fft._pocketfft.pypocketfft"]
    assert seen[None][:3] == ["0", "True", "False"]


def test_the_numbers_are_written_before_the_figure(tmp_path, monkeypatch, capsys):
    """A figure that cannot be drawn (here: the disk fills up in savefig) leaves the CSV files
    and summary.json complete: they are written first."""
    from leonav_runtime.beacons import pipeline

    args = _simulated_capture(tmp_path, shared_file("tle/starlink_2026-02-23.txt"))
    out = tmp_path / "o"

    def full_disk(res, path):
        assert (out / "summary.json").is_file() and (out / "doppler_rate_measurements.csv").is_file()
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(pipeline, "plot_waterfall", full_disk)
    assert main(args + ["--out", str(out)]) == 3
    assert "waterfall.png: no space left on the device" in capsys.readouterr().err   # one line naming the file
    assert json.loads((out / "summary.json").read_text())["counts"]["associated"] == 3
    assert len(list(csv.DictReader((out / "doppler_rate_measurements.csv").open()))) > 0
    assert not (out / "waterfall.png").exists()
