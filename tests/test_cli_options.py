"""Command-line conveniences: --version and provenance, sweep options without a TOML edit,
explicit time zones, read-only commands that write nothing, SigMF by default, the minimum
capture length, warnings printed once, and -v/-q."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from leonav_runtime.common import provenance
from leonav_runtime.cli import main
from tests.conftest import shared_file

REPO = Path(__file__).resolve().parents[1]
TINY = ["--counts", "5", "--modes", "gps+imu", "--trials", "2", "--workers", "1", "--no-progress"]


def _git_head() -> str | None:
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None


def test_version_names_the_package_and_the_commit(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    out = capsys.readouterr().out
    from importlib import metadata

    assert out.startswith(f"leonav {metadata.version('leonav')}")
    head = _git_head()
    if head:
        assert f"git {head[:12]}" in out


def test_scenario_hash_follows_content_not_layout():
    a = {"time": {"duration_s": 20.0, "epoch": "2026-02-23T12:00:00Z"}, "name": "x"}
    b = {"name": "x", "time": {"epoch": "2026-02-23T12:00:00Z", "duration_s": 20.0}}
    assert provenance.scenario_hash(a) == provenance.scenario_hash(b)
    assert provenance.scenario_hash(a) != provenance.scenario_hash({**a, "name": "y"})


def test_sweep_options_change_the_run_and_are_recorded(tmp_path, monkeypatch):
    import tomli_w

    from leonav_runtime.sweep import plots as sweep_plots
    from leonav_runtime.scenarios.load import load_scenario

    monkeypatch.setattr(sweep_plots, "plot_all", lambda *a, **k: None)  # figures: tests/test_figures.py
    raw = load_scenario("paper").raw
    raw["time"]["duration_s"] = 2.0  # a short run; the options under test change the rest
    (tmp_path / "short.toml").write_text(tomli_w.dumps(raw))
    runs = {}
    for seed in (1, 2):
        out = tmp_path / f"s{seed}"
        argv = ["sweep", str(tmp_path / "short.toml"), "--counts", "5,10", "--modes", "gps+imu", "leo-alpha+imu",
                "--seed", str(seed), "--trials", "2", "--workers", "1", "--no-progress", "--out", str(out)]
        assert main(argv) == 0
        runs[seed] = json.loads((out / "metrics.json").read_text())
    m = runs[1]
    assert m["scenario"]["modes"] == ["gps+imu", "leo-alpha+imu"] and m["scenario"]["counts"] == [5, 10]
    assert {(r["mode"], r["count"]) for r in m["results"]} == {(a, c) for a in ("gps+imu", "leo-alpha+imu")
                                                               for c in (5, 10)}
    p = m["provenance"]
    assert p["command_line"].startswith("leonav sweep ") and "--counts 5,10 --modes gps+imu" in p["command_line"]
    assert "--seed 1" in p["command_line"]
    assert p["scenario_sha256"] != runs[2]["provenance"]["scenario_sha256"]
    assert p["git_commit"] == _git_head()
    # the seed reaches the trials: other noise, other RMSE
    assert m["results"][0]["position"]["rmse"] != runs[2]["results"][0]["position"]["rmse"]
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib
    config = tomllib.loads((tmp_path / "s1" / "config.toml").read_text())
    assert config["monte_carlo"]["seed"] == 1 and config["starlink"]["counts"] == [5, 10]
    assert config["monte_carlo"]["trials"] == 2      # rerunning config.toml repeats the run


@pytest.mark.parametrize("argv,needle", [
    (["sweep", "--modes", "gps+imu,warp-drive"], "--modes: 'warp-drive'"),
    (["sweep", "--counts", "5:x"], "--counts: '5:x'"),
    (["sweep", "--counts", "0"], "counts 1..10000"),
    (["sweep", "--counts", "1:2000000000"], "--counts: '1:2000000000'"),   # refused before 2e9 ints are built
    (["sweep", "--counts", "5,20000"], "--counts: '20000'"),
    (["sweep", "--counts", "5,,10"], "empty item"),
    (["sweep", "--counts", "5,10,"], "empty item"),
])
def test_bad_sweep_options_are_one_line_errors(tmp_path, capsys, argv, needle):
    assert main(argv + ["--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert needle in err and err.count("\n") == 1
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("argv", [["sky", "--start", "2026-02-23T12:00:00"],
                                  ["tle", "info", "x.tle", "--epoch", "2026-02-23T12:00:00"],
                                  ["beacons", "x.cu8", "--simulate", "--start", "2026-02-23T06:00:00"]])
def test_a_time_without_a_zone_is_refused(tmp_path, capsys, argv):
    assert main(argv + ["--out", str(tmp_path / "o")]) == 2
    assert "has no time zone" in capsys.readouterr().err


def test_tle_info_writes_nothing_unless_asked(tmp_path, monkeypatch, capsys):
    tle = shared_file("tle/gps-ops_2026-03-09.txt")
    monkeypatch.chdir(tmp_path)
    assert main(["tle", "info", str(tle), "--epoch", "2026-03-09T12:00:00Z"]) == 0
    assert list(tmp_path.iterdir()) == []
    assert "32 gps element sets" in capsys.readouterr().out


def test_beacons_simulate_writes_sigmf_warns_once_and_quiet_silences(tmp_path, capsys):
    tle = shared_file("tle/starlink_2026-02-23.txt")  # holds element sets weeks older than the start
    common = ["--simulate", "--tle", str(tle), "--duration", "4.5", "--sim-rate", "250e3", "--band", "250e3",
              "--n-sats", "2", "--start", "2026-02-23T06:00:00Z"]
    assert main(["beacons", str(tmp_path / "sim.cu8"), *common, "--out", str(tmp_path / "o")]) == 0
    assert sorted(p.name for p in tmp_path.glob("sim*")) == ["sim.sigmf-data", "sim.sigmf-meta"]
    err = capsys.readouterr().err
    stale = [ln for ln in err.splitlines() if "stale elements" in ln]
    assert len(stale) == 1 and stale[0].startswith("leonav beacons: warning: ") and ".py" not in err
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["provenance"]["leonav_version"] and summary["counts"]["associated"] == 2
    assert main(["-q", "beacons", str(tmp_path / "sim.sigmf-meta"), "--tle", str(tle),
                 "--out", str(tmp_path / "o2")]) == 0
    assert "stale" not in capsys.readouterr().err


def test_a_too_short_capture_is_refused_with_the_minimum(tmp_path, capsys):
    tle = shared_file("tle/starlink_2026-02-23.txt")
    rc = main(["beacons", str(tmp_path / "s.cu8"), "--simulate", "--tle", str(tle), "--duration", "4",
               "--sim-rate", "250e3", "--band", "250e3", "--start", "2026-02-23T06:00:00Z",
               "--out", str(tmp_path / "o")])
    assert rc == 2
    err = capsys.readouterr().err
    assert "association needs at least 4.0" in err and not (tmp_path / "o").exists()
    with pytest.raises(SystemExit):
        main(["beacons", "--help"])
    assert "Minimum capture length" in capsys.readouterr().out.replace("\n", " ")


def test_verbosity_flags_set_the_log_level():
    from leonav_runtime.cli import _split_verbosity
    from leonav_runtime.common.log_setup import level_for

    argv, level = _split_verbosity(["sweep", "-v", "--trials", "2", "-v"])
    assert argv == ["sweep", "--trials", "2"] and level == 2 and level_for(level) == 10
    assert _split_verbosity(["-q", "sky", "--", "-v"]) == (["sky", "--", "-v"], -1)
    assert level_for(-1) == 40 and level_for(0) == 30 and level_for(1) == 20


def test_spp_and_study_results_carry_provenance(tmp_path):
    """Every results JSON names the version, commit and command line that made it."""
    obs, nav = shared_file("gnss_rinex/30400920.05o"), shared_file("gnss_rinex/30400920.05n")
    assert main(["spp", str(obs), "--nav", str(nav), "--out", str(tmp_path / "spp")]) == 0
    p = json.loads((tmp_path / "spp" / "spp.json").read_text())["provenance"]
    assert p["command_line"].startswith("leonav spp ") and p["git_commit"] == _git_head()
    study = tmp_path / "s.toml"
    study.write_text('name = "s"\nscenario = "paper"\nmodes = ["gps+imu"]\ncount = 5\ntrials = 1\n'
                     '[set]\n"time.duration_s" = 1.0\n[[vary]]\nkey = "starlink.rate_hz"\nvalues = [1, 2]\n')
    assert main(["study", str(study), "--workers", "1", "--no-progress", "--out", str(tmp_path / "st")]) == 0
    p = json.loads((tmp_path / "st" / "study.json").read_text())["provenance"]
    assert p["command_line"].startswith("leonav study ") and len(p["scenario_sha256"]) == 64


@pytest.mark.parametrize("argv,prog,needle", [
    (["tle", "fetch", "starlink", "--format", "bogus"], "leonav tle fetch", "invalid choice: 'bogus'"),
    (["sweep", "--seed", "abc"], "leonav sweep", "invalid int value: 'abc'"),
    (["study"], "leonav study", "required: STUDY"),
    (["sweep", "--bogus"], "leonav sweep", "unrecognized arguments: --bogus"),
    (["nosuchcmd"], "leonav", "invalid choice: 'nosuchcmd'"),
])
def test_argparse_errors_are_one_line_with_exit_2(capsys, argv, prog, needle):
    try:
        status = main(argv)
    except SystemExit as exc:   # argparse's own errors leave through sys.exit
        status = exc.code
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "usage:" not in err
    assert err.startswith(f"{prog}: error: ") and needle in err


def test_help_still_prints_the_usage(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["sweep", "--help"])
    out = capsys.readouterr().out
    assert exc.value.code == 0 and out.startswith("usage: leonav sweep") and "--counts" in out


def test_the_recorded_version_is_pyprojects_and_the_installed_one():
    """provenance.version() reads leonav_runtime.__version__ (no importlib.metadata on a command's
    path): it must be the version pyproject.toml declares and the installed metadata reports."""
    import re
    from importlib import metadata

    declared = re.search(r'(?m)^version = "([^"]+)"', (REPO / "pyproject.toml").read_text()).group(1)
    assert provenance.version() == declared == metadata.version("leonav")


def test_git_commit_dirty_follows_the_tracked_files(tmp_path):
    import shutil

    if shutil.which("git") is None:
        pytest.skip("git is not installed")
    env = {"GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME": "t",
           "GIT_COMMITTER_EMAIL": "t@t", "HOME": str(tmp_path), "PATH": "/usr/bin:/bin"}
    own = tmp_path / "own"
    (own / "leonav_runtime").mkdir(parents=True)
    (own / "pyproject.toml").write_text('[project]\nname = "leonav"\n')
    subprocess.run(["git", "init", "-q"], cwd=own, check=True, env=env, capture_output=True)
    assert provenance.git_commit_of(own / "leonav_runtime") is None          # no commit yet
    for args in (["add", "-A"], ["commit", "-q", "-m", "x"]):
        subprocess.run(["git", *args], cwd=own, check=True, env=env, capture_output=True)
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=own, check=True, capture_output=True,
                          text=True).stdout.strip()
    (own / "untracked.txt").write_text("x")                                   # untracked: still clean
    assert provenance.git_commit_of(own / "leonav_runtime") == {"commit": head, "dirty": False}
    (own / "pyproject.toml").write_text('[project]\nname = "leonav"\nversion = "9"\n')
    assert provenance.git_commit_of(own / "leonav_runtime") == {"commit": head, "dirty": True}


def test_git_commit_only_for_leonavs_own_tree(tmp_path):
    import shutil

    if shutil.which("git") is None:
        pytest.skip("git is not installed")

    def repo(path: Path) -> str:
        path.mkdir(parents=True, exist_ok=True)
        env = {"GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME": "t",
               "GIT_COMMITTER_EMAIL": "t@t", "HOME": str(tmp_path), "PATH": "/usr/bin:/bin"}
        for args in (["init", "-q"], ["add", "-A"], ["commit", "-q", "--allow-empty", "-m", "x"]):
            subprocess.run(["git", *args], cwd=path, check=True, env=env, capture_output=True)
        return subprocess.run(["git", "rev-parse", "HEAD"], cwd=path, check=True, capture_output=True,
                              text=True).stdout.strip()

    # an installed copy inside some other project's repository (a venv in a project): no commit
    site = tmp_path / "project" / ".venv" / "site-packages" / "leonav_runtime"
    site.mkdir(parents=True)
    repo(tmp_path / "project")
    assert provenance.git_commit_of(site) is None
    # a leonav tree nested below another repository's top: not leonav's own commit
    nested = tmp_path / "outer" / "vendor" / "leonav"
    (nested / "leonav_runtime").mkdir(parents=True)
    (nested / "pyproject.toml").write_text('[project]\nname = "leonav"\n')
    repo(tmp_path / "outer")
    assert provenance.git_commit_of(nested / "leonav_runtime") is None
    # leonav's own checkout: its HEAD
    own = tmp_path / "own"
    (own / "leonav_runtime").mkdir(parents=True)
    (own / "pyproject.toml").write_text('[project]\nname = "leonav"\n')
    head = repo(own)
    assert provenance.git_commit_of(own / "leonav_runtime") == {"commit": head, "dirty": False}
    # and this checkout
    if _git_head():
        assert provenance.git_commit_of(REPO / "leonav_runtime")["commit"] == _git_head()
