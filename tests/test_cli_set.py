"""--set section.key=value: values read by the schema's declared type, on sweep as on study."""
from __future__ import annotations

import tomllib

import pytest

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.study.spec import parse_set


def test_values_are_read_by_the_keys_type():
    assert parse_set("time.epoch=2026-02-24T00:00:00Z") == ("time.epoch", "2026-02-24T00:00:00Z")
    assert parse_set('time.epoch="2026-02-24T00:00:00Z"') == ("time.epoch", "2026-02-24T00:00:00Z")
    assert parse_set("site.lat_deg=-33.87") == ("site.lat_deg", -33.87)
    assert parse_set("starlink.counts=5,10") == ("starlink.counts", [5, 10])
    assert parse_set("starlink.counts=[5, 10]") == ("starlink.counts", [5, 10])


def test_a_wrong_value_is_one_line_in_the_users_words():
    with pytest.raises(UserInputError, match=r"--set site\.lat_deg=north: expected a number$"):
        parse_set("site.lat_deg=north")
    with pytest.raises(UserInputError, match=r"unknown scenario key 'site.lat'.*did you mean site.lat_deg"):
        parse_set("site.lat=1")


def test_sweep_takes_set_and_writes_the_effective_config(tmp_path, capsys):
    from leonav_runtime.cli import main

    out = tmp_path / "sweep"
    rc = main(["sweep", "--set", "time.epoch=2026-02-24T00:00:00Z", "--set", "site.lat_deg=-33.87",
               "--set", "time.duration_s=10", "--modes", "gps+imu", "--counts", "5", "--trials", "2",
               "--no-progress", "--out", str(out)])
    assert rc == 0, capsys.readouterr().err
    cfg = tomllib.loads((out / "config.toml").read_text())
    assert cfg["time"]["epoch"] == "2026-02-24T00:00:00Z" and cfg["site"]["lat_deg"] == -33.87
    assert main(["sweep", "--set", "site.lat_deg=north", "--out", str(tmp_path / "bad")]) == 2
    assert "expected a number" in capsys.readouterr().err
