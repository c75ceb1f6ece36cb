"""Hostile scenario files and run sizes: one clear line naming the file and field, never a
traceback, and no run that would need more memory than the limit (checked before anything
is allocated; the user raises the limit with LEONAV_MAX_MEMORY_MB).

The fuzz test mutates the built-in scenarios (truncate, flip bytes, duplicate/delete lines,
swap values for other types and sizes): only UserInputError escapes `load_scenario`, and a
mutant whose TOML content is unchanged loads to the same scenario.
"""
from __future__ import annotations

import copy
import datetime as dt
import json
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from leonav_runtime.common import output
from leonav_runtime.cli import EXIT_BAD_INPUT, main
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.scenarios.load import BUILTIN_DIR, load_scenario, scenario_from_dict
from leonav_runtime.common.utc import parse_utc
from tests.timebox import bounded

REPO = Path(__file__).resolve().parents[1]
PAPER = BUILTIN_DIR / "paper.toml"
MARITIME = BUILTIN_DIR / "maritime-outage.toml"
MEMORY_ENV = "LEONAV_MAX_MEMORY_MB"



def _write(tmp_path: Path, text: str, name: str = "s.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _edit(text: str, section: str, key: str, value: str) -> str:
    """`text` with `key = value` in [section] (replaced, or added at the section's top)."""
    lines = text.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.strip() == f"[{section}]") if section else -1
    for i in range(head + 1, len(lines)):
        if lines[i].startswith("["):
            break
        if lines[i].split("=")[0].strip() == key:
            end, depth = i, lines[i].split("#")[0].count("[") - lines[i].split("#")[0].count("]")
            while depth > 0:   # a value spread over several lines
                end += 1
                depth += lines[end].split("#")[0].count("[") - lines[end].split("#")[0].count("]")
            lines[i:end + 1] = [f"{key} = {value}"]
            return "\n".join(lines) + "\n"
    lines.insert(head + 1, f"{key} = {value}")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------ tracebacks before


def test_unknown_top_level_section_is_named(tmp_path):
    # before: TypeError while formatting its own message (list | set)
    path = _write(tmp_path, PAPER.read_text() + "\n[gnss]\nrate_hz = 1.0\n")
    with pytest.raises(UserInputError, match=r"s\.toml: unknown section or key 'gnss'; expected one of .*starlink"):
        load_scenario(path)


def test_non_utf8_or_a_directory_is_named(tmp_path):
    # before: UnicodeDecodeError / IsADirectoryError without the scenario's name
    path = tmp_path / "latin1.toml"
    path.write_bytes(PAPER.read_bytes().replace(b"Rochester", b"Rochester \xe9"))
    with pytest.raises(UserInputError, match=r"latin1\.toml: not UTF-8 text \(byte \d+\)"):
        load_scenario(path)
    with pytest.raises(UserInputError, match=rf"{tmp_path}: is a directory, expected a scenario TOML file"):
        load_scenario(tmp_path)


def test_deep_nesting_and_huge_files_are_named(tmp_path):
    deep = _write(tmp_path, "a = " + "[" * 50_000 + "]" * 50_000 + "\n", "deep.toml")
    with bounded(10), pytest.raises(UserInputError, match=r"deep\.toml: .*nested too deeply"):
        load_scenario(deep)
    big = tmp_path / "big.toml"
    with open(big, "wb") as fh:
        fh.truncate(50_000_000)   # sparse: no disk
    with bounded(5), pytest.raises(UserInputError, match=r"big\.toml: 50\.0 MB is more than a scenario file"):
        load_scenario(big)


@pytest.mark.parametrize("section,key,value,words", [
    ("gps", "rate_hz", "0.01", r"\[gps\] rate_hz = 0.01: one epoch every 100 s.*20"),
    ("starlink", "rate_hz", "0.02", r"\[starlink\] rate_hz = 0.02: one epoch every 50 s"),
    ("gps", "rate_hz", "3.0", r"\[gps\] rate_hz = 3: .*must divide the IMU rate 100"),
    ("trajectory", "maneuvers", "[[5.0, 1e12, 0.0]]", r"maneuvers\[0\] acceleration 1e\+12 m/s\^2: expected"),
    ("trajectory", "maneuvers", "[[5.0, 0.0, 1e6]]", r"maneuvers\[0\] turn rate 1e\+06 deg/s: expected"),
    ("trajectory", "maneuvers", "[[5.0, 100.0, 0.0]]", r"maneuvers make the speed 508 m/s at 5 s"),
    ("trajectory", "maneuvers", "[[5.0, -3.0, 0.0]]", r"maneuvers make the speed -7 m/s at 5 s"),
    ("trajectory", "attitude_deg", "[0.0, 0.0, 1e300]", r"attitude_deg.*expected a list of 3 numbers in deg"),
    ("time", "duration_s", "1" + "0" * 400, r"\[time\] duration_s = 1000.*expected s in"),
    ("starlink", "counts", "[5, 10000000]", r"\[starlink\] counts.*expected .* integers >= 1 \(at most 10000\)"),
    ("time", "epoch", '"0001-01-01T00:00:00+01:00"', r"\[time\] epoch: '0001-01-01T00:00:00\+01:00' is out of range"),
    ("time", "epoch", "2026-02-23T12:00:00Z", r"\[time\] epoch = datetime.*expected a str"),
    ("elements", "files", '["a\\u0000b.tle"]', r"\[elements\] files.*expected a list of paths"),
], ids=["gps-rate-no-epoch", "starlink-rate-no-epoch", "gps-rate-not-dividing", "accel-1e12", "turn-1e6",
        "speed-500", "speed-negative", "attitude-1e300", "duration-10^400", "counts-huge", "epoch-overflow",
        "epoch-toml-datetime", "file-nul"])
def test_values_that_used_to_crash_a_run_are_refused_at_load(tmp_path, section, key, value, words):
    # before: ValueError (empty epochs in SGP4/EOP), LinAlgError (Newton on 1e12 m/s^2),
    # OverflowError (int beyond float) ... out of `leonav sweep`, or a silently odd run
    text = _edit(MARITIME.read_text() if section == "trajectory" else PAPER.read_text(), section, key, value)
    text = _edit(text, "time", "duration_s", "20.0") if key != "duration_s" else text
    text = text.replace("outages_s = [[120.0, 210.0]]", "outages_s = []")
    with bounded(10), pytest.raises(UserInputError, match=words):
        load_scenario(_write(tmp_path, text))


def test_a_name_never_leaves_the_results_folder(tmp_path, monkeypatch):
    # before: name = "../../../x" wrote the results three folders above ./leonav-out
    text = _edit(PAPER.read_text(), "", "name", '"../../../x"')
    with pytest.raises(UserInputError, match=r"name = '\.\./\.\./\.\./x': expected 1-64 letters, digits"):
        load_scenario(_write(tmp_path, text))
    monkeypatch.chdir(tmp_path)
    out = output.results_dir(None, "sweep-../../../x")
    assert out.resolve().parent == (tmp_path / "leonav-out").resolve()


# ------------------------------------------------------------------ run size


def test_a_long_run_is_refused_before_anything_is_allocated(tmp_path, monkeypatch):
    # before: duration_s = 20000 (allowed by the schema) grew to 23.8 GB and was killed
    import resource

    monkeypatch.delenv(MEMORY_ENV, raising=False)
    path = _write(tmp_path, _edit(PAPER.read_text(), "time", "duration_s", "20000.0"))
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    with bounded(5), pytest.raises(UserInputError, match=rf"needs about [\d,]+ MB.*more than the limit .*{MEMORY_ENV}"):
        load_scenario(path)
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 50_000   # kB
    monkeypatch.setenv(MEMORY_ENV, "1000000000")   # the user's own limit
    assert load_scenario(path).duration_s == 20000.0
    monkeypatch.setenv(MEMORY_ENV, "lots")
    with pytest.raises(UserInputError, match=f"{MEMORY_ENV}='lots': expected a positive number of megabytes"):
        load_scenario(path)


@pytest.mark.parametrize("args,words", [
    (["--trials", "1000000000"], r"--trials 1000000000: expected 1\.\.100000"),
    (["--trials", "100000"], rf"needs about .* MB.*{MEMORY_ENV}"),
    (["--workers", "100000"], rf"needs about .* MB.*--workers.*{MEMORY_ENV}"),
])
def test_sweep_size_options_are_checked_before_work(tmp_path, capsys, monkeypatch, args, words):
    # before: --trials 1e9 built its task list at ~120 MB/s
    monkeypatch.setenv(MEMORY_ENV, "8000")
    with bounded(10):
        rc = main(["sweep", "paper", *args, "--no-progress", "--out", str(tmp_path / "o")])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert rc == EXIT_BAD_INPUT and len(err) == 1 and err[0].startswith("leonav sweep: error: "), err
    import re
    assert re.search(words, err[0]), err[0]
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_the_estimate_covers_a_measured_run(tmp_path):
    """Peak allocation of preparing the paper scenario (GPS + Starlink, 60 s) and one trial,
    measured in a fresh process, is below the estimate, and the estimate within 4x of it."""
    # tracemalloc (NumPy reports its buffers to it): the peak of what the run itself allocates,
    # independent of what the process touched before (ru_maxrss was 0 on a machine whose peak
    # came earlier)
    code = (
        "import copy, json, sys, tracemalloc\n"
        "from leonav_runtime.scenarios.load import load_scenario, scenario_from_dict\n"
        "from leonav_runtime.sweep import montecarlo as mc\nfrom leonav_runtime.core import navfuncs\n"
        "navfuncs.NavFunctions()\n"
        "b = load_scenario('paper'); raw = copy.deepcopy(b.raw)\n"
        "raw['time']['duration_s'] = 60.0; raw['monte_carlo']['modes'] = ['gps+leo-alpha+imu']\n"
        "scn = scenario_from_dict(raw, source=b.source)\n"
        "tracemalloc.start()\n"
        "mc.run_trial(scn, 'gps+leo-alpha+imu', 45, 0)\n"
        "peak = tracemalloc.get_traced_memory()[1]\n"
        "from leonav_runtime.scenarios.run_size import memory_estimate\n"
        "from leonav_runtime.scenarios.load import mode_of\n"
        "est = memory_estimate(scn, mode_of, trials=0, workers=1)\n"
        "print(json.dumps({'measured': peak, 'est': est}))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=REPO)
    assert proc.returncode == 0, proc.stderr
    res = json.loads(proc.stdout.strip().splitlines()[-1])
    work = res["est"]["setup"] + res["est"]["trial"]
    assert res["measured"] < work < 4 * res["measured"] + 30e6, res


# ------------------------------------------------------------------ UTC fields


@pytest.mark.parametrize("value,words", [
    ("0001-01-01T00:00:00+01:00", "is out of range"),
    ("9999-12-31T23:59:59-01:00", "is out of range"),
    (20260223, "expected an ISO 8601 time as text, got int"),
    (None, "expected an ISO 8601 time as text, got NoneType"),
    (["2026-02-23"], "expected an ISO 8601 time as text, got list"),
    ("2026-02-30T00:00:00Z", "is not an ISO 8601 time"),
])
def test_parse_utc_raises_only_user_input_errors_naming_the_field(value, words):
    # before: OverflowError for the first two, and 20260223 (an int) was read as a date
    with pytest.raises(UserInputError, match=rf"^--start: .*{words}"):
        parse_utc(value, "--start")
    assert parse_utc("2026-02-23T12:00:00+01:00", "--start") == dt.datetime(2026, 2, 23, 11, tzinfo=dt.timezone.utc)


# ------------------------------------------------------------------ fuzzing


HOSTILE_VALUES = ["1e400", "-1e400", "nan", "inf", "1" + "0" * 40, "-1", "0", "true", '"x"', '""', "[]", "[[]]",
                  "[1, [2, [3]]]", "{a = 1}", "2026-02-23T12:00:00Z", '"' + "x" * 2000 + '"', "[1e308, 1e308, 1e308]",
                  '["gps+imu", "gps+imu"]', "[0.0, 0.0, 0.0]", "[[0.0, 0.0, 0.0]]", "[[1.0, 2.0]]"]


def _mutate_toml(text: str, rng) -> str:
    lines = text.splitlines(keepends=True)
    kind = int(rng.integers(0, 6))
    if kind == 0:
        return text[: int(rng.integers(0, len(text)))]
    if kind == 1:
        data = bytearray(text.encode())
        for _ in range(int(rng.integers(1, 4))):
            data[int(rng.integers(0, len(data)))] = int(rng.integers(0, 256))
        return data.decode("utf-8", errors="surrogateescape")
    i = int(rng.integers(0, len(lines)))
    if kind == 2:
        return "".join(lines[:i] + lines[i + 1:])
    if kind == 3:
        return "".join(lines[:i] + [lines[int(rng.integers(0, len(lines)))]] + lines[i:])
    value_lines = [j for j, ln in enumerate(lines) if "=" in ln and not ln.lstrip().startswith("#")]
    j = value_lines[int(rng.integers(0, len(value_lines)))]
    key = lines[j].split("=")[0]
    lines[j] = f"{key}= {HOSTILE_VALUES[int(rng.integers(0, len(HOSTILE_VALUES)))]}\n"
    return "".join(lines)


def _fields(s) -> dict:
    return {k: v for k, v in vars(s).items() if k not in ("source", "raw")}


@pytest.mark.parametrize("base", [PAPER, MARITIME], ids=["paper", "maritime"])
def test_fuzz_scenario_files(tmp_path, base, monkeypatch):
    monkeypatch.delenv(MEMORY_ENV, raising=False)
    text = base.read_text()
    original = tomllib.loads(text)
    ref = _fields(load_scenario(base))
    rng = np.random.default_rng(15)
    loaded = refused = 0
    with bounded(30):
        for k in range(150):
            mutant = _mutate_toml(text, rng)
            path = tmp_path / f"m{k}.toml"
            path.write_bytes(mutant.encode("utf-8", errors="surrogateescape"))
            try:
                scn = load_scenario(path)
            except UserInputError as exc:
                assert str(path) in str(exc) and "\n" not in str(exc).strip(), str(exc)
                refused += 1
                continue
            loaded += 1
            assert math_ok(scn)
            try:
                same = tomllib.loads(mutant) == original
            except tomllib.TOMLDecodeError:
                same = False
            if same:
                assert _fields(scn) == ref
            # what was accepted is accepted again from its own values (no order or type surprises)
            again = scenario_from_dict(copy.deepcopy(scn.raw), source=str(path), base_dir=path.parent)
            assert _fields(again) == _fields(scn)
    assert loaded > 10 and refused > 10


def math_ok(scn) -> bool:
    import math

    numbers = [scn.duration_s, scn.imu_rate_hz, scn.lat_rad, scn.lon_rad, scn.alt_m,
               scn.gps["rate_hz"], scn.starlink["rate_hz"], *scn.trajectory["attitude_rad"]]
    return all(math.isfinite(x) for x in numbers) and 0 < scn.duration_s <= 86400 and scn.name
