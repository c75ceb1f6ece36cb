"""Scenario TOML: built-ins load, every shipped line has a unit comment, bad fields are named."""
from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.scenarios.load import BUILTIN_DIR, builtin_scenarios, load_scenario


def test_builtin_scenarios_load_in_si():
    assert {"paper", "maritime-outage"} <= set(builtin_scenarios())
    paper = load_scenario("paper")
    assert paper.lat_rad == pytest.approx(math.radians(43.0848638))
    assert paper.trajectory["attitude_rad"] == pytest.approx([0, 0, math.pi / 2])
    assert paper.starlink["counts"] == list(range(5, 50, 5))
    assert paper.gps["elevation_mask_rad"] == pytest.approx(math.radians(10))
    assert paper.starlink["elevation_mask_rad"] == pytest.approx(math.radians(28))
    sea = load_scenario("maritime-outage")
    (start, end), = sea.gps["outages"]
    assert end - start >= 60 and 0 < start and end < sea.duration_s
    assert sum(m[0] for m in sea.trajectory["maneuvers"]) == pytest.approx(sea.duration_s)


@pytest.mark.parametrize("path", sorted(BUILTIN_DIR.glob("*.toml")), ids=lambda p: p.name)
def test_every_value_line_has_a_unit_comment(path):
    for lineno, line in enumerate(path.read_text().splitlines(), 1):
        if re.match(r"^\s*[A-Za-z_]+\s*=", line):
            assert "#" in line, f"{path.name}:{lineno} has no unit comment: {line!r}"


def _write(tmp_path, body):
    path = tmp_path / "s.toml"
    path.write_text('[time]\nepoch = "2026-02-23T12:00:00Z"\nduration_s = 20.0\n' + body)
    return path


@pytest.mark.parametrize(
    "body, needle",
    [
        ("[site]\nlat_deg = 123.0\n", "[site] lat_deg = 123.0: expected deg in [-90, 90]"),
        ("[site]\nlat_deg = 'north'\n", "[site] lat_deg = 'north': expected a float in deg"),
        ("[site]\nlatitude = 43.0\n", "[site] unknown key 'latitude'"),
        ("[imu]\nprofile = 'navigation'\n", "expected one of tactical, wt901"),
        ("[gps]\noutages_s = [[30.0, 10.0]]\n", "outages_s[0] = [30.0, 10.0]: expected 0 <= start < end"),
        ("[starlink]\ncounts = [5, 0]\n", "counts = [5, 0]: expected a non-empty list of integers >= 1"),
        ("[monte_carlo]\nmodes = ['gps+imu', 'magic']\n", "modes: 'magic': unknown word 'magic'"),
        ("[trajectory]\nattitude_deg = [0, 90]\n", "attitude_deg = [0, 90]: expected a list of 3 numbers"),
    ],
)
def test_bad_fields_are_named_with_value_and_expectation(tmp_path, body, needle):
    path = _write(tmp_path, body)
    with pytest.raises(UserInputError) as err:
        load_scenario(path)
    assert needle in str(err.value)
    assert str(path) in str(err.value)


def test_missing_required_and_bad_epoch(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text("[time]\nepoch = '2026-02-23T12:00:00Z'\n")
    with pytest.raises(UserInputError, match=r"\[time\] duration_s is missing"):
        load_scenario(path)
    path.write_text("[time]\nepoch = '2026-02-23 12:00'\nduration_s = 1.0\n")
    with pytest.raises(UserInputError, match="has no time zone: expected an explicit one"):
        load_scenario(path)
    path.write_text("[time\n")
    with pytest.raises(UserInputError, match="not valid TOML"):
        load_scenario(path)
    with pytest.raises(UserInputError, match="built-in scenarios: .*paper"):
        load_scenario(tmp_path / "nope.toml")


def test_scenario_reference_doc_matches_the_schema():
    from leonav_runtime.scenarios.load import schema_markdown

    doc = (BUILTIN_DIR.parents[1] / "docs" / "scenarios.md").read_text()
    assert schema_markdown() in doc, "docs/scenarios.md is stale: paste scenario.schema_markdown() under '## Keys'"


# ---- values at the edges: NaN/inf/bool, inclusive bounds, lists, conversions ----------------


@pytest.mark.parametrize("body, needle", [
    ("[site]\nlat_deg = nan\n", "[site] lat_deg = nan: expected a finite number in deg"),
    ("[site]\nalt_m = inf\n", "[site] alt_m = inf: expected a finite number in m"),
    ("[gps]\npseudorange_sigma_m = -inf\n", "pseudorange_sigma_m = -inf: expected a finite number"),
    ("[starlink]\nlo_offset_hz = nan\n", "lo_offset_hz = nan: expected a finite number"),
    ("[site]\nlat_deg = true\n", "[site] lat_deg = True: expected a float in deg"),
    ("[gps]\nmax_satellites = true\n", "[gps] max_satellites = True: expected a int"),
    ("[monte_carlo]\ntrials = false\n", "[monte_carlo] trials = False: expected a int"),
    ("[gps]\nmax_satellites = 8.0\n", "[gps] max_satellites = 8.0: expected a int"),
    ("[trajectory]\nattitude_deg = [0, nan, 90]\n", "attitude_deg = [0, nan, 90]: expected a list of 3 numbers"),
    ("[trajectory]\nattitude_deg = [true, 0, 90]\n", "attitude_deg = [True, 0, 90]: expected a list of 3 numbers"),
    ("[trajectory]\nmaneuvers = [[10.0, inf, 0.0]]\n", "maneuvers[0] = [10.0, inf, 0.0]"),
    ("[trajectory]\nmaneuvers = [[0.0, 0.1, 0.0]]\n", "maneuvers[0] duration 0 s: expected 0.001..86400 s"),
    ("[trajectory]\nkind = 'flying'\n", "[trajectory] kind = 'flying': expected one of static, maneuvers"),
    ("[gps]\noutages_s = [[10.0, 20.5]]\n", "outages_s[0] = [10.0, 20.5]: expected 0 <= start < end <= duration"),
    ("[gps]\noutages_s = [[-1.0, 5.0]]\n", "outages_s[0] = [-1.0, 5.0]"),
    ("[gps]\noutages_s = [[nan, 5.0]]\n", "outages_s[0] = [nan, 5.0]"),
    ("[starlink]\ncounts = [5, true]\n", "counts = [5, True]: expected a non-empty list of integers >= 1"),
    ("[starlink]\ncounts = []\n", "counts = []: expected a non-empty list"),
    ("[gps]\noutages_s = [[5.0, 5.0]]\n", "outages_s[0] = [5.0, 5.0]: expected 0 <= start < end"),
    ("[elements]\nsource = 'files'\n", "[elements] source = 'files' but files is empty"),
    ("[site]\nlat_deg = 90.000001\n", "expected deg in [-90, 90]"),
    ("[site]\nlat_deg = -90.000001\n", "expected deg in [-90, 90]"),
    ("[gps]\nmax_satellites = 3\n", "[gps] max_satellites = 3: expected - in [4, 64]"),
    ("[gps]\nmax_satellites = 65\n", "[gps] max_satellites = 65: expected - in [4, 64]"),
    ("[time]\nduration_s = 86400.001\n", "duration_s = 86400.001"),
])
def test_non_finite_boolean_and_out_of_range_values_are_named(tmp_path, body, needle):
    path = tmp_path / "s.toml"
    text = '[time]\nepoch = "2026-02-23T12:00:00Z"\nduration_s = 20.0\n' + body
    if body.startswith("[time]"):  # replaces the default duration
        text = '[time]\nepoch = "2026-02-23T12:00:00Z"\n' + body.split("\n", 1)[1]
    path.write_text(text)
    with pytest.raises(UserInputError) as err:
        load_scenario(path)
    assert needle in str(err.value)


def _load(tmp_path, body, duration="20.0"):
    path = tmp_path / "s.toml"
    path.write_text(f'[time]\nepoch = "2026-02-23T12:00:00Z"\nduration_s = {duration}\n' + body)
    return load_scenario(path)


def test_bounds_are_inclusive(tmp_path, monkeypatch):
    monkeypatch.setenv("LEONAV_MAX_MEMORY_MB", "1e9")  # a day at the default rates is refused by default
    s = _load(tmp_path, "[site]\nlat_deg = 90.0\nlon_deg = 360.0\nalt_m = -500.0\n[gps]\nmax_satellites = 4\n"
                        "elevation_mask_deg = -5.0\n[monte_carlo]\ntrials = 1\nseed = 0\n"
                        "[filter]\ngate_nis = 0.0\n", duration="86400.0")
    assert (s.lat_rad, s.lon_rad, s.alt_m) == (pytest.approx(math.pi / 2), pytest.approx(2 * math.pi), -500.0)
    assert s.gps["max_satellites"] == 4 and s.trials == 1 and s.seed == 0 and s.duration_s == 86400.0
    assert s.gps["elevation_mask_rad"] == pytest.approx(math.radians(-5.0)) and s.filter["gate_nis"] == 0.0
    # (the shortest duration_s, 0.001 s, is refused by the rate check: no GNSS epoch inside it)
    s = _load(tmp_path, "[site]\nlat_deg = -90.0\n[gps]\nmax_satellites = 64\n", duration="1.0")
    assert s.lat_rad == pytest.approx(-math.pi / 2) and s.gps["max_satellites"] == 64


def test_integers_are_accepted_for_float_fields_and_units_converted(tmp_path):
    s = _load(tmp_path, "[site]\nlat_deg = 43\nalt_m = 170\n[trajectory]\nroll_amplitude_deg = 10\n"
                        "pitch_amplitude_deg = 5\n[filter]\ninitial_attitude_sigma_deg = 2\n"
                        "[gps]\noutages_s = [[5, 20]]\n")
    assert s.lat_rad == pytest.approx(math.radians(43.0)) and s.alt_m == 170.0 and isinstance(s.alt_m, float)
    assert s.trajectory["roll_amplitude_rad"] == pytest.approx(math.radians(10.0))
    assert s.trajectory["pitch_amplitude_rad"] == pytest.approx(math.radians(5.0))
    assert s.filter["initial_attitude_sigma_rad"] == pytest.approx(math.radians(2.0))
    assert s.gps["outages"] == [(5.0, 20.0)]   # an outage may end with the run


def test_lists_are_normalised_and_paths_relative_to_the_file(tmp_path):
    assert _load(tmp_path, "[starlink]\ncounts = [1]\n").starlink["counts"] == [1]
    path = tmp_path / "typo.toml"
    path.write_text('nmae = "x"\n[time]\nepoch = "2026-02-23T12:00:00Z"\nduration_s = 20.0\n')
    with pytest.raises(UserInputError, match="unknown section or key 'nmae'"):
        load_scenario(path)
    s = _load(tmp_path, "[starlink]\ncounts = [10, 5, 10]\n[monte_carlo]\n"
                        "modes = ['leo-alpha+imu', 'gps+imu', 'leo-alpha+imu']\n"
                        "[elements]\nsource = 'files'\nfiles = ['sub/gps.tle', '/abs/sl.tle']\n")
    assert s.starlink["counts"] == [5, 10]
    assert s.modes == ["leo-alpha+imu", "gps+imu"]
    assert s.element_files == [tmp_path / "sub" / "gps.tle", Path("/abs/sl.tle")]
