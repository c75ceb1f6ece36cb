"""Operator ephemerides in place of element sets in `leonav replay` (--operator-ephemerides):
the Doppler-rate table's satellite states come from the files where they cover the
satellite, and a replay with files that put the satellites 3 km off their true orbits does
worse than one with files on them."""
from __future__ import annotations

import datetime as dt
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
# the covariance of a public file's first record, rounded (m^2, m^2/s^2): 0.7-1.1 m, 1-2 mm/s
COV_UVW = np.diag([0.46, 0.78, 1.21, 2.0e-6, 5.2e-7, 5.4e-6])


def _starlink():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return default_elements(EPOCH)["starlink"]


def _ahead(es, along_m: float, cov) -> OperatorEphemerisSet:
    """Operator files of `es` whose orbits are along_m further along the true ones (an
    in-track error): the SGP4 states of along_m / 7.6 km/s later, labelled with these times."""
    lead = dt.timedelta(seconds=along_m / 7600.0)
    made = ephemerides_from_elements(es, EPOCH + lead, np.arange(-120.0, 241.0, 60.0), cov)
    for e in made.ephemerides.values():
        e.start_utc, e.stop_utc = e.start_utc - lead, e.stop_utc - lead
    return made


def test_the_doppler_rate_table_takes_states_from_the_files_that_cover_them():
    es = _starlink()
    made = _ahead(es.select([0]), 1000.0, COV_UVW)
    t = np.array([1.0, 2.0, 3.0, 1.5, 2.5])
    meas = BeaconMeasurements(t, es.norad_ids[[0, 0, 0, 1, 1]], np.array([0, 0, 0, 1, 1]), np.zeros(5), np.ones(5))
    notes: list[str] = []
    with_files = doppler_rate_table(meas, es, EPOCH, 0.5, made, notes)
    plain = doppler_rate_table(meas, es, EPOCH, 0.5)
    moved = np.linalg.norm(with_files.sat_ecef[:, 0:3] - plain.sat_ecef[:, 0:3], axis=1)
    assert np.abs(moved[:3] - 1000.0).max() < 5.0                 # satellite 0 from its file, 1 km ahead
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


@pytest.mark.slow
def test_replay_with_operator_ephemerides(session, tmp_path, capsys):
    es = _starlink()
    es = es.select(np.flatnonzero(np.isin(es.norad_ids, session.sdr_info["norad_ids"])))   # the capture's
    for name, along in (("on", 0.0), ("off", 3000.0)):
        for k, e in enumerate(_ahead(es, along, COV_UVW).ephemerides.values()):
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
    assert rmse["off"] > 1.2 * rmse["on"]                            # 3 km in-track off: worse (5.39 -> 7.43 m)
    capsys.readouterr()
    assert leonav_main(["replay", *common, "--operator-ephemerides", str(tmp_path / "out-on"),
                        "--out", str(tmp_path / "out-bad")]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no usable operator ephemeris" in err[0], err


def test_replay_doppler_rate_r_carries_the_files_covariance(session, tmp_path):
    from leonav_runtime import replay
    es = _starlink()
    es = es.select(np.flatnonzero(np.isin(es.norad_ids, session.sdr_info["norad_ids"])))
    t_nodes = np.arange(-120.0, 241.0, 60.0)
    big = COV_UVW * 1e4                       # 100 x the sigmas: 0.1-0.2 m/s, the term is visible
    for name, cov in (("x1", big), ("x4", 4.0 * big)):
        for k, e in enumerate(ephemerides_from_elements(es, EPOCH, t_nodes, cov).ephemerides.values()):
            write_file(e, tmp_path / name, serial=k)

    def alpha_r(folder):
        opts = replay.ReplayOptions(modes=("leo-alpha+imu",), operator_ephemerides=folder)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            inputs = replay.decode_inputs(session.folder, opts)
        return inputs.records["doppler_rate"]["R"], inputs.notes
    base, _ = alpha_r(None)
    r1, notes = alpha_r(str(tmp_path / "x1"))
    r4, _ = alpha_r(str(tmp_path / "x4"))
    assert "beacons: doppler-rate R + J P J^T of the operator covariance; 0 records without it" in notes
    assert (r1 - base).min() > 0
    assert r4 - base == pytest.approx(4.0 * (r1 - base), rel=1e-6)      # R follows the files
