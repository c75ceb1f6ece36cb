"""Operator ephemerides in place of element sets in `leonav replay` (--operator-ephemerides):
the Doppler-rate table's satellite states come from the files where they cover the
satellite, and a replay with files that put the satellites 3 km off their true orbits does
worse than one with files on them."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from leonav_runtime.cli import main as leonav_main
from leonav_runtime.orbits import default_elements
from leonav_runtime.orbits.operator_ephemeris import OperatorEphemerisSet, write_file
from leonav_runtime.orbits.operator_states import ephemerides_from_elements
from leonav_runtime.replay.beacon_table import BeaconMeasurements, doppler_rate_table
from leonav_runtime.simulation import session_synth as ss

EPOCH = ss.PAPER_EPOCH


def _starlink():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return default_elements(EPOCH)["starlink"]


def _shifted(made: OperatorEphemerisSet, along_m: float) -> OperatorEphemerisSet:
    """The files' orbits moved along the velocity by along_m (an in-track error)."""
    for e in made.ephemerides.values():
        e.r_eme2000_m = e.r_eme2000_m + along_m * e.v_eme2000_mps / np.linalg.norm(e.v_eme2000_mps, axis=1,
                                                                                   keepdims=True)
    return made


def test_the_doppler_rate_table_takes_states_from_the_files_that_cover_them():
    es = _starlink()
    t_nodes = np.arange(-120.0, 241.0, 60.0)
    made = _shifted(ephemerides_from_elements(es.select([0]), EPOCH, t_nodes, np.eye(6)), 1000.0)
    t = np.array([1.0, 2.0, 3.0, 1.5, 2.5])
    meas = BeaconMeasurements(t, es.norad_ids[[0, 0, 0, 1, 1]], np.array([0, 0, 0, 1, 1]), np.zeros(5), np.ones(5))
    notes: list[str] = []
    with_files = doppler_rate_table(meas, es, EPOCH, 0.5, made, notes)
    plain = doppler_rate_table(meas, es, EPOCH, 0.5)
    moved = np.linalg.norm(with_files.sat_ecef[:, 0:3] - plain.sat_ecef[:, 0:3], axis=1)
    assert np.abs(moved[:3] - 1000.0).max() < 1.0                 # satellite 0 from its (shifted) file
    np.testing.assert_array_equal(with_files.sat_ecef[3:], plain.sat_ecef[3:])   # satellite 1: no file
    assert notes == ["beacons: 1 of 2 satellites' states from operator ephemerides, 1 from their element sets "
                     "(no file, or not over their measurement times)"]


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    return ss.write_synthetic_session(tmp_path_factory.mktemp("session") / "s",
                                      ss.SynthSessionConfig(seconds=12.0, seed=1))


def _metrics(out):
    import json
    return json.loads((out / "metrics.json").read_text())


def test_replay_with_operator_ephemerides(session, tmp_path, capsys):
    es = _starlink()
    es = es.select(np.flatnonzero(np.isin(es.norad_ids, session.sdr_info["norad_ids"])))   # the capture's
    t_nodes = np.arange(-120.0, 241.0, 60.0)
    for name, along in (("on", 0.0), ("off", 3000.0)):
        made = _shifted(ephemerides_from_elements(es, EPOCH, t_nodes, np.eye(6)), along)
        for k, e in enumerate(made.ephemerides.values()):
            write_file(e, tmp_path / name, serial=k)
    common = [str(session.folder), "--modes", "leo-alpha+imu", "-q"]
    runs = {}
    for name in ("elements", "on", "off"):
        extra = [] if name == "elements" else ["--operator-ephemerides", str(tmp_path / name)]
        assert leonav_main(["replay", *common, *extra, "--out", str(tmp_path / f"out-{name}")]) == 0
        runs[name] = _metrics(tmp_path / f"out-{name}")
    rmse = {k: v["modes"]["leo-alpha+imu"]["rmse_position_m"] for k, v in runs.items()}
    assert any("satellites' states from operator ephemerides, 0 from their element sets" in n
               for n in runs["on"]["notes"])
    assert rmse["on"] == pytest.approx(rmse["elements"], rel=0.02)   # the files hold the same orbits
    assert rmse["off"] > 1.2 * rmse["on"]                            # 3 km in-track off: worse (5.4 -> 7.8 m)
    capsys.readouterr()
    assert leonav_main(["replay", *common, "--operator-ephemerides", str(tmp_path / "out-on"),
                        "--out", str(tmp_path / "out-bad")]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no usable operator ephemeris" in err[0], err
