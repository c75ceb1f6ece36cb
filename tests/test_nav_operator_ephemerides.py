"""Operator ephemerides in `leonav nav` (--operator-ephemerides): the streamed Doppler-rate takes
its satellites' states from the files as they are first measured and the files' covariance in
its R, so fast playback of a session follows `leonav replay` with the same folder; without the
files it does not, and a folder that is not one is refused in one line."""
from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from tests.test_nav_live import difference_rms, nav_options, run_nav_records
from tests.test_operator_replay import COV_UVW, EPOCH, _ahead, _starlink
from leonav_runtime.orbits.operator_ephemeris import write_file
from leonav_runtime.orbits.operator_states import ephemerides_from_elements

MODE = "leo-alpha+imu"


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """A 10 s session, operator files of its satellites with 100x a public file's sigmas (so the
    consider term is visible), and the replay with that folder."""
    from leonav_runtime.replay import ReplayOptions, replay_session
    from leonav_runtime.simulation import session_synth as ss

    base = tmp_path_factory.mktemp("navoperator")
    made = ss.write_synthetic_session(base / "s", ss.SynthSessionConfig(seconds=10.0, seed=0, sdr_rate_hz=240e3))
    es = _starlink()
    es = es.select(np.flatnonzero(np.isin(es.norad_ids, made.sdr_info["norad_ids"])))
    for k, e in enumerate(_ahead(es, 3000.0, COV_UVW).ephemerides.values()):
        write_file(e, base / "files-ahead", serial=k)
    for name, scale in (("files", 1.0), ("files-x4", 4.0)):
        files = ephemerides_from_elements(es, EPOCH, np.arange(-120.0, 241.0, 60.0), scale * COV_UVW * 1e4)
        for k, e in enumerate(files.ephemerides.values()):
            write_file(e, base / name, serial=k)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        replay_session(base / "s", base / "replay", ReplayOptions(modes=(MODE,), operator_ephemerides=str(base / "files")))
    return base, len(files.ephemerides)


def _run(out, session, folder=None):
    """run_nav in fast playback; also the R of every Doppler-rate record the road released."""
    res, alpha = run_nav_records(nav_options(out, mode=MODE, session=session, operator_ephemerides=folder),
                                 "doppler_rate")
    return res, alpha["R"]


def test_fast_playback_with_the_files_follows_the_replay_with_them(pair):
    base, n_files = pair
    with_files, r1 = _run(base / "nav-files", base / "s", str(base / "files"))
    _, r4 = _run(base / "nav-files-x4", base / "s", str(base / "files-x4"))
    plain, r0 = _run(base / "nav-plain", base / "s")
    assert with_files["exit_code"] == 0 and plain["exit_code"] == 0
    road = with_files["road"]
    released = road["doppler_rate_released"]
    assert released >= 20
    assert road["doppler_rate_operator_covariance"] == released          # every record took the files' term
    assert road.get("doppler_rate_without_operator_covariance", 0) == 0
    op = json.loads((base / "nav-files" / "nav.json").read_text())["operator_ephemerides"]
    assert op["satellites_with_file"] >= 2 and op["satellites_with_file"] <= n_files
    assert op["satellites_without_file"] == 0 and op["files_refused"] == 0 and op["refused"] == []
    rms, n, sigma = difference_rms(base / "nav-files", base / "replay", MODE)
    assert n > 80 and rms < sigma, (rms, sigma)
    # the files' covariance is in R: every record's R grows, four times the covariance four times as much
    assert r0.size == r1.size == r4.size == released
    assert (r1 - r0).min() > 0
    assert r4 - r0 == pytest.approx(4.0 * (r1 - r0), rel=1e-6)


def test_a_folder_that_is_not_one_is_refused_in_one_line(pair, tmp_path, capsys):
    from leonav_runtime.cli import main

    base, _ = pair
    args = ["nav", "--from", str(base / "s"), "--mode", MODE, "--nmea-port", "0", "-q", "--out", str(tmp_path / "o")]
    assert main(args + ["--operator-ephemerides", str(tmp_path / "none")]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--operator-ephemerides" in err[0] and "not a folder" in err[0], err
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(args + ["--operator-ephemerides", str(empty)]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "lists no operator-ephemeris file" in err[0], err


def _child_tables(session, folder, tmp, carrier_phase: bool = False, kind: str = "table"):
    """The live path's beacon process body (`beacon_process._child`), run in this thread on the
    whole recorded capture: the tables it sends. Its metadata copy leaves out the host stamp of
    the first sample, so that the lag is counted in capture time (read at once, not live)."""
    import math
    import queue
    import threading

    from leonav_runtime.beacons import capture_io
    from leonav_runtime.nav.beacon_process import _child
    from leonav_runtime.simulation.session_synth import ROCHESTER

    info = capture_io.open_capture(session / "sdr.cu8")
    start = info.start_utc.timestamp()
    inbox, outbox = queue.Queue(), queue.Queue()
    inbox.put(("site", (math.radians(ROCHESTER[0]), math.radians(ROCHESTER[1]), ROCHESTER[2]), start, start))
    done, stop = threading.Event(), threading.Event()
    done.set()
    meta = json.loads((session / "sdr.sigmf-meta").read_text())
    meta["global"].pop("leonav:t_mono_start_s", None)
    (tmp / "sdr.sigmf-meta").write_text(json.dumps(meta))
    _child(str(session / "sdr.cu8"), str(tmp / "sdr.sigmf-meta"), info.rf_center_hz, (), 0.5,
           inbox, outbox, done, stop, folder, carrier_phase)
    msgs = [outbox.get() for _ in range(outbox.qsize())]
    assert msgs[-1][0] == "summary" and not msgs[-1][1]["error"], msgs[-1]
    return [m for m in msgs if m[0] == kind], msgs[-1][1]


def test_the_live_beacon_process_takes_the_states_from_the_files(pair, tmp_path):
    base, _ = pair
    plain, _ = _child_tables(base / "s", None, tmp_path)
    ahead, summary = _child_tables(base / "s", str(base / "files-ahead"), tmp_path)
    assert len(plain) == len(ahead) >= 3
    for p, a in zip(plain, ahead):
        np.testing.assert_array_equal(p[1], a[1])             # the same measurements, times and satellites
        np.testing.assert_array_equal(p[2], a[2])
        moved = np.linalg.norm(a[5][:, 0:3] - p[5][:, 0:3], axis=1)
        assert np.all(np.abs(moved - 3000.0) < 20.0), moved    # every satellite from its file, 3 km along
        assert set(a[6]) == set(int(i) for i in a[2])          # the names ride along for the road's files
    assert summary["counts"]["states_from_operator_files"] == sum(t[1].size for t in ahead)


def test_the_folder_reads_each_satellite_once_and_keeps_each_refusal_once(pair):
    from leonav_runtime.orbits.operator_folder import OperatorFolder

    base, n_files = pair
    manifest = (base / "files" / "MANIFEST.txt").read_text()
    bad = base / "files-bad-line"
    bad.mkdir(exist_ok=True)
    for p in (base / "files").glob("MEME_*.txt"):
        (bad / p.name).write_bytes(p.read_bytes())
    (bad / "MANIFEST.txt").write_text(manifest + "sub/elsewhere.txt\n")
    folder = OperatorFolder(bad)
    names = sorted(folder.listed)
    assert len(names) == n_files
    for k, name in enumerate(names):           # satellites met one by one, and again
        assert folder.ensure({k: name}) == [name]
        assert folder.ensure({k: name}) == []
    assert folder.ensure({99999: "STARLINK-NOFILE"}) == []
    assert folder.counts == {"satellites_with_file": n_files, "satellites_without_file": 1, "files_refused": 0}
    assert len(folder.set.rejected) == 1 and "sub/elsewhere.txt" in folder.set.rejected[0][1]
