"""Hostile session folders for `leonav replay`, and results files that are never half written.

The session is built from real bytes: the Trimble 10 Hz NMEA log (gnss.raw) and the WT901SD
WitMotion recording (imu.raw), with the chunk index and session.json the recorder writes.
Each damaged file used to end in a traceback (AttributeError, TypeError, RecursionError,
UnicodeDecodeError, OverflowError) or in a silently odd replay; now it is one UserInputError
naming the file (and line). The seeded fuzz test mutates every file of the folder.
"""
from __future__ import annotations

import errno
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from leonav.hardware.session_decode import decode_session
from leonav.hardware.session_files import RawLog, session_json
from leonav_runtime import replay
from leonav_runtime.common import output
from leonav_runtime.core import navfuncs
from leonav_runtime.cli import EXIT_BAD_INPUT, main
from leonav_runtime.common.errors import UserInputError
from tests.conftest import shared_file
from tests.timebox import bounded

TRUTH = "utc_unix_s,lat_deg,lon_deg,h_m,v_e_mps,v_n_mps,v_u_mps,roll_rad,pitch_rad,yaw_rad"



def real_session(folder: Path, n_imu: int = 300) -> Path:
    """A session folder from real bytes: GGA+RMC epochs at 10 Hz, WitMotion cycles at 10 Hz."""
    folder.mkdir(parents=True, exist_ok=True)
    lines = [ln + b"\n" for ln in shared_file("nmea/gpsd/nmea-rtk.log").read_bytes().split(b"\n")
             if ln.startswith(b"$")]
    gnss = RawLog(folder, "gnss")
    for k in range(0, len(lines) - 1, 2):
        gnss.write(lines[k] + lines[k + 1], 1000.02 + 0.05 * k)
    gnss.close()
    data = shared_file("imu/witmotion/wt901sd_example_data.TXT").read_bytes()[:44 * n_imu]
    imu = RawLog(folder, "imu")
    for k in range(n_imu):
        imu.write(data[44 * k:44 * k + 44], 999.95 + 0.1 * k)
    imu.close()
    devices = [{"kind": "gnss", "port": "/dev/ttyAMA0", "baud": 38400}, {"kind": "imu", "port": "/dev/ttyUSB0",
                                                                         "baud": 9600}]
    (folder / "session.json").write_text(json.dumps(session_json("complete", "2020-03-18T13:28:19+00:00", 999.9,
                                                                 devices)))
    return folder


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    return real_session(tmp_path_factory.mktemp("real") / "session")


@pytest.fixture(scope="module")
def nav():
    return navfuncs.NavFunctions()


def _copy(base: Path, tmp_path: Path) -> Path:
    dst = tmp_path / "s"
    shutil.copytree(base, dst)
    return dst


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines()


def _put(path: Path, lines: list[str]) -> None:
    path.write_text("\n".join(lines) + "\n")


def _set_stamp(f: Path, name: str, row: int, value: str) -> None:
    lines = _lines(f / name)
    lines[row] = f"{value},{lines[row].split(',')[1]}"
    _put(f / name, lines)


def _json(f: Path, edit) -> None:
    info = json.loads((f / "session.json").read_text())
    edit(info)
    (f / "session.json").write_text(json.dumps(info))


def _no_gnss(f: Path) -> None:   # the host clock of session.json is then the time axis
    (f / "gnss.raw").write_bytes(b"")
    (f / "gnss.chunks.csv").write_text("t_mono_s,end_offset\n")


CASES = {
    # before: ValueError (NaN stamps) / ... ; now the file is named
    "index-missing": (lambda f: (f / "imu.chunks.csv").unlink(), r"imu\.chunks\.csv: missing"),
    "gnss-index-missing": (lambda f: (f / "gnss.chunks.csv").unlink(), r"gnss\.chunks\.csv: missing"),
    "index-nan": (lambda f: _set_stamp(f, "imu.chunks.csv", 5, "nan"), r"imu\.chunks\.csv:6: t_mono_s nan"),
    "index-inf": (lambda f: _set_stamp(f, "imu.chunks.csv", 5, "inf"), r"imu\.chunks\.csv:6: t_mono_s inf"),
    "index-1e300": (lambda f: _set_stamp(f, "imu.chunks.csv", 1, "1e300"), r"imu\.chunks\.csv:2: t_mono_s 1e300"),
    "index-backwards": (lambda f: _set_stamp(f, "imu.chunks.csv", 10, "950.0"), r"imu\.chunks\.csv:11: .* earlier"),
    "index-constant": (lambda f: _put(f / "imu.chunks.csv", [_lines(f / "imu.chunks.csv")[0]] + [
        "1000.0," + ln.split(",")[1] for ln in _lines(f / "imu.chunks.csv")[1:]]), r"imu\.chunks\.csv: .* do not advance"),
    "index-garbage": (lambda f: _set_stamp(f, "imu.chunks.csv", 3, "x"), r"imu\.chunks\.csv:4: expected"),
    "json-array": (lambda f: (f / "session.json").write_text("[1, 2, 3]"), r"session\.json: expected a JSON object"),
    "json-nested": (lambda f: (f / "session.json").write_text("[" * 100_000 + "]" * 100_000),
                    r"session\.json: .*nested too deeply"),
    "json-latin1": (lambda f: (f / "session.json").write_bytes(b'{"status": "caf\xe9"}'),
                    r"session\.json: not UTF-8 text \(byte 15\)"),
    "json-devices-object": (lambda f: _json(f, lambda d: d.update(devices={"gnss": 1})), r"session\.json: devices"),
    "json-device-text": (lambda f: _json(f, lambda d: d["devices"].__setitem__(1, "imu")), r"session\.json: devices"),
    "json-start-number": (lambda f: (_no_gnss(f), _json(f, lambda d: d.update(start_utc=12))),
                          r"session\.json: start_utc"),
    "json-start-garbage": (lambda f: (_no_gnss(f), _json(f, lambda d: d.update(start_utc="yesterday"))),
                           r"session\.json: start_utc 'yesterday'"),
    "json-t0-text": (lambda f: (_no_gnss(f), _json(f, lambda d: d.update(t_mono_start_s="x"))),
                     r"session\.json: t_mono_start_s"),
    "truth-cut": (lambda f: (f / "truth.csv").write_text(TRUTH + "\n" + "".join(
        f"{1584538100.0 + 0.1 * k},41.57,-93.75,250.0,0,0,0,0,0,0\n" for k in range(50)) + "1584538105.0,41.5"),
                  r"truth\.csv:52: 2 of 10 fields \(the file is cut short\)"),
    "truth-latin1": (lambda f: (f / "truth.csv").write_bytes(TRUTH.encode() + b"\n1,\xe9\n"),
                     r"truth\.csv: not UTF-8 text"),
    "truth-nan": (lambda f: (f / "truth.csv").write_text(TRUTH + "\n1584538100.0,nan,-93.75,250.0,0,0,0,0,0,0\n"),
                  r"truth\.csv:2: expected finite numbers"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_damaged_session_files_are_one_clear_error(base, nav, tmp_path, case):
    damage, words = CASES[case]
    folder = _copy(base, tmp_path)
    damage(folder)
    with bounded(20), pytest.raises(UserInputError, match=words):
        replay.replay_session(folder, tmp_path / "out", nav=nav)


def test_the_cli_reports_a_damaged_session_in_one_line(base, tmp_path, capsys):
    folder = _copy(base, tmp_path)
    (folder / "session.json").write_text("[]")
    assert main(["replay", str(folder), "--out", str(tmp_path / "o")]) == EXIT_BAD_INPUT
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith("leonav replay: error: ") and "session.json" in err[0], err


def test_the_undamaged_session_replays(base, nav, tmp_path):
    m = replay.replay_session(_copy(base, tmp_path), tmp_path / "out", nav=nav)
    assert m["modes"]["fix+imu"]["rmse_position_m"] < 5.0 and m["counts"]["gnss_fixes"] > 100


def test_a_line_cut_at_the_end_of_the_index_is_what_a_kill_leaves(base, tmp_path):
    folder = _copy(base, tmp_path)
    text = (folder / "imu.chunks.csv").read_text()
    (folder / "imu.chunks.csv").write_text(text[:-8])    # the last line cut mid-number
    dec = decode_session(folder)
    assert len(dec.imu_samples) == 300               # its bytes are decoded with the last stamp


# ------------------------------------------------------------------ results files


def test_results_files_are_never_half_written(tmp_path):
    # before: a full disk during write_csv left a truncated CSV where the old one had been
    path = output.write_csv(tmp_path / "rmse.csv", ["a", "b"], [[1.0, 2.0]])
    before = path.read_bytes()

    def rows():
        yield [3.0, 4.0]
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with pytest.raises(OSError) as info:
        output.write_csv(path, ["a", "b"], rows())
    assert info.value.errno == errno.ENOSPC
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["rmse.csv"]     # no temporary file left
    with pytest.raises(OSError) as info:
        output.write_csv(tmp_path / "missing" / "x.csv", ["a"], [])
    assert info.value.filename == str(tmp_path / "missing" / "x.csv")


# ------------------------------------------------------------------ fuzzing


def _mutate_bytes(data: bytes, rng) -> tuple[bytes, int]:
    if not data:
        return data, 0
    kind = int(rng.integers(0, 3))
    if kind == 0:
        cut = int(rng.integers(0, len(data)))
        return data[:cut], cut
    out = bytearray(data)
    i = int(rng.integers(0, len(data)))
    if kind == 1:
        for k in range(int(rng.integers(1, 4))):
            out[min(len(data) - 1, i + k * int(rng.integers(0, 50)))] = int(rng.integers(0, 256))
    else:
        lines = data.split(b"\n")
        j = int(rng.integers(0, len(lines)))
        lines[j] = lines[int(rng.integers(0, len(lines)))]
        out = bytearray(b"\n".join(lines))
    changed = next((k for k in range(min(len(out), len(data))) if out[k] != data[k]), min(len(out), len(data)))
    return bytes(out), changed


def test_fuzz_session_folders(base, nav, tmp_path):
    files = ["gnss.raw", "imu.raw", "gnss.chunks.csv", "imu.chunks.csv", "session.json"]
    clean = decode_session(base)
    assert clean.gnss_summary["rejected"] == {} and len(clean.imu_samples) == 300
    rng = np.random.default_rng(15)
    outcomes = {"ok": 0, "refused": 0}
    with bounded(40):
        for k in range(60):
            folder = tmp_path / f"m{k}"
            shutil.copytree(base, folder)
            name = files[k % len(files)]
            mutant, offset = _mutate_bytes((folder / name).read_bytes(), rng)
            (folder / name).write_bytes(mutant)
            try:
                inputs = replay.decode_inputs(folder, replay.ReplayOptions(), nav=nav)
            except UserInputError as exc:
                assert "\n" not in str(exc).strip()
                outcomes["refused"] += 1
                continue
            outcomes["ok"] += 1
            dec = decode_session(folder)
            # every byte of the raw logs is in a record or a counted rejection; the records of
            # the untouched prefix are the original ones
            if name == "gnss.raw":
                done = [float(t) for t, end in (ln.split(",") for ln in _lines(base / "gnss.chunks.csv")[1:])
                        if int(end) <= offset]   # chunks wholly before the first changed byte
                ref = [r for r in clean.gnss_records if done and r.t_mono_s <= done[-1]]
                assert [repr(r) for r in dec.gnss_records[:len(ref)]] == [repr(r) for r in ref]
            if name == "imu.raw":
                n = max(0, offset // 44 - 1)
                assert [s.f_b_mps2 for s in dec.imu_samples[:n]] == [s.f_b_mps2 for s in clean.imu_samples[:n]]
            assert inputs.imu.t.size > 0
    assert outcomes["ok"] > 10 and outcomes["refused"] > 5, outcomes
