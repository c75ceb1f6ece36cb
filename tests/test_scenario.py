"""Scenario TOML: built-ins load, every shipped line has a unit comment, bad fields are named."""
from __future__ import annotations

import math
import re

import pytest

from leonav_runtime.errors import UserInputError
from leonav_runtime.scenario import BUILTIN_DIR, builtin_scenarios, load_scenario


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
        ("[monte_carlo]\nmodes = ['gps+imu', 'magic']\n", "modes contains 'magic'"),
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
    with pytest.raises(UserInputError, match="expected an explicit UTC offset"):
        load_scenario(path)
    path.write_text("[time\n")
    with pytest.raises(UserInputError, match="not valid TOML"):
        load_scenario(path)
    with pytest.raises(UserInputError, match="built-in scenarios: .*paper"):
        load_scenario(tmp_path / "nope.toml")


def test_scenario_reference_doc_matches_the_schema():
    from leonav_runtime.scenario import schema_markdown

    doc = (BUILTIN_DIR.parents[1] / "docs" / "scenarios.md").read_text()
    assert schema_markdown() in doc, "docs/scenarios.md is stale: paste scenario.schema_markdown() under '## Keys'"
