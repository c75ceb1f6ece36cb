"""Hostile captures and options for the beacon pipeline: no hang, bounded memory, one line.

A noise-free full-scale tone (thousands of quantization spurs), long captures, absurd
options and broken metadata. Every case is small, seeded and bounded in time (`bounded`
turns a hang into a failure).
"""
from __future__ import annotations

import json
import time
import tracemalloc

import numpy as np
import pytest

from leonav_runtime.beacons import capture_io, pipeline
from leonav_runtime.beacons.ridges import Ridge, RidgeTracker, TrackerConfig
from leonav_runtime.cli import main
from leonav_runtime.common.errors import UserInputError
from tests.conftest import shared_file
from tests.timebox import bounded

FS = 250e3



def _cu8(path, x, fs=FS, start="2026-02-23T06:00:00Z"):
    path.write_bytes(capture_io.quantize_cu8(x, 1.0).tobytes())
    capture_io.write_side_json(path, fs, 1.575e9, 9.75e9, None, {"start_utc": start} if start else None)
    return path


def _cw(seconds: float, fs: float = FS) -> np.ndarray:
    t = np.arange(int(seconds * fs)) / fs
    return np.exp(2j * np.pi * 12345.6 * t).astype(np.complex64)


def _tones(seconds: float, seed: int, fs: float = FS, offset: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    n = int(seconds * fs)
    t = (offset + np.arange(n)) / fs
    x = (0.1 * (rng.standard_normal(n) + 1j * rng.standard_normal(n))).astype(np.complex64)
    for f0, a in ((-60e3, 40.0), (30e3, -25.0)):
        x += (0.03 * np.exp(2j * np.pi * (f0 * t + 0.5 * a * t * t))).astype(np.complex64)
    return x


# ------------------------------------------------------------------ hangs and memory


def test_noise_free_full_scale_tone_does_not_hang(tmp_path):
    # quantizing a pure full-scale tone fills the band with spurs: ~650 fragments here took 71 s
    # to join (the join was cubic; 4,007 fragments at 2.4 MS/s ran for more than 20 CPU-minutes)
    info = capture_io.open_capture(_cu8(tmp_path / "cw.cu8", _cw(8.0)))
    with bounded(30):
        t0 = time.process_time()
        ridges, stats, _, _ = pipeline.extract_ridges(info, pipeline.PipelineConfig(band_hz=FS))
        assert time.process_time() - t0 < 25
    assert stats.births > 1000 and stats.joined > 0 and ridges


def test_join_is_near_linear_in_fragments():
    rng = np.random.default_rng(4)
    f_hz = np.arange(-2048, 2048) * 60.0
    tracker = RidgeTracker(f_hz, TrackerConfig())
    frags = []
    for k in range(4000):  # short stationary fragments, dense in time and frequency
        t0 = rng.uniform(0, 60)
        t = t0 + np.arange(12) * 0.02
        frags.append(Ridge(t, np.full(t.size, rng.uniform(-1e5, 1e5)), np.full(t.size, 20.0)))
    with bounded(10):
        out = tracker._join(sorted(frags, key=lambda r: r.t_s[0]))
    assert len(out) + tracker.stats.joined == 4000


def test_tracker_caps_are_counted_and_reported(tmp_path):
    info = capture_io.open_capture(_cu8(tmp_path / "cw.cu8", _cw(3.0)))
    cfg = pipeline.PipelineConfig(band_hz=FS, tracker=TrackerConfig(max_active=16, max_fragments=5))
    with bounded(30):
        ridges, stats, _, _ = pipeline.extract_ridges(info, cfg)
    assert stats.births_refused > 0 and stats.fragments_dropped > 0
    notes = stats.notes()
    assert any("limit of simultaneous ridges" in n for n in notes) and any("max_fragments" in n for n in notes)


def _peak_mb(path) -> float:
    info = capture_io.open_capture(path)
    tracemalloc.start()
    try:
        pipeline.extract_ridges(info, pipeline.PipelineConfig(band_hz=FS))
        return tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()


def _long_capture(path, pieces: int):
    with open(path, "wb") as fh:
        for k in range(pieces):  # 8 s pieces of one continuous signal, written one at a time
            fh.write(capture_io.quantize_cu8(_tones(8.0, 1 + k, offset=int(k * 8 * FS)), 1.0).tobytes())
    capture_io.write_side_json(path, FS, 1.575e9, 9.75e9, None)
    return path


@pytest.mark.slow
def test_memory_does_not_grow_with_capture_length(tmp_path):
    # the waterfall kept every STFT row: ~1.5 MB per capture second here (35 MB at 8 s, 71 MB
    # at 32 s); now it is averaged as it streams (at most 800 rows, 6.5 MB)
    with bounded(60):
        small = _peak_mb(_long_capture(tmp_path / "16s.cu8", 2))
        large = _peak_mb(_long_capture(tmp_path / "32s.cu8", 4))
    assert large - small < 3.0, (small, large)


# ------------------------------------------------------------------ options and metadata


def _capture(tmp_path, seconds=1.0):
    return _cu8(tmp_path / "c.cu8", _tones(seconds, 0))


def _run(args, capsys, timeout=30):
    with bounded(timeout):
        rc = main(args)
    err = capsys.readouterr().err.strip().splitlines()
    return rc, err


@pytest.mark.parametrize("option,value,expected", [
    ("--fft-size", "1", "--fft-size"), ("--fft-size", "0", "--fft-size"), ("--fft-size", "1000000000", "--fft-size"),
    ("--band", "nan", "--band"), ("--band", "-5", "--band"), ("--band", "1", "--band"),
    ("--interval", "0", "--interval"), ("--interval", "nan", "--interval"), ("--interval", "-1", "--interval"),
    ("--interval", "1e-9", "--interval"), ("--lat", "nan", "--lat"), ("--lon", "inf", "--lon"),
    ("--mask", "200", "--mask"), ("--tone-freq", "nan", "--tone-freq"), ("--dc-notch", "nan", "--dc-notch"),
    ("--sample-rate", "1e12", "--sample-rate"),
])
def test_absurd_options_are_one_clear_line(tmp_path, capsys, option, value, expected):
    tle = shared_file("tle/starlink_2026-02-23.txt")
    rc, err = _run(["beacons", str(_capture(tmp_path)), "--tle", str(tle), option, value,
                    "--out", str(tmp_path / "o")], capsys)
    assert rc == 2 and len(err) == 1, err
    assert err[0].startswith("leonav beacons: error: ") and expected in err[0], err


@pytest.mark.parametrize("option,value", [("--duration", "1e7"), ("--sim-rate", "1e12"), ("--n-sats", "100000"),
                                          ("--cn0", "nan"), ("--lo-drift", "inf")])
def test_absurd_simulation_is_refused_before_anything_is_written(tmp_path, capsys, option, value):
    tle = shared_file("tle/starlink_2026-02-23.txt")
    rc, err = _run(["beacons", str(tmp_path / "sim.cu8"), "--simulate", "--tle", str(tle), option, value,
                    "--start", "2026-02-23T06:00:00Z", "--out", str(tmp_path / "o")], capsys)
    assert rc == 2 and len(err) == 1 and option in err[0], err
    assert not (tmp_path / "sim.cu8").exists()


def _side(tmp_path, content: bytes):
    cap = tmp_path / "c.cu8"
    cap.write_bytes(capture_io.quantize_cu8(_tones(0.5, 0), 1.0).tobytes())
    (tmp_path / "c.cu8.json").write_bytes(content)
    return cap


@pytest.mark.parametrize("content,expected", [
    (json.dumps({"sample_rate_hz": 1e12, "center_freq_hz": 1.575e9}).encode(), "sample_rate_hz"),
    (json.dumps({"sample_rate_hz": 0.001, "center_freq_hz": 1.575e9}).encode(), "sample_rate_hz"),
    (b'{"sample_rate_hz": 250000, "center_freq_hz": 1.575e9, "note": "\xff\xfe caf\xe9"}', "UTF-8"),
    (b"[" * 100_000 + b"]" * 100_000, "nested"),
    (json.dumps({"sample_rate_hz": [[[250e3]]], "center_freq_hz": 1.575e9}).encode(), "sample_rate_hz"),
    (json.dumps({"sample_rate_hz": 250e3, "center_freq_hz": 1.575e9, "start_utc": {"a": [1]}}).encode(),
     "start_utc"),
    (json.dumps({"sample_rate_hz": 250e3, "center_freq_hz": 1.575e9, "start_utc": "0001-01-01T00:00:00+01:00"}).encode(),
     "start_utc"),
])
def test_broken_side_files_are_one_clear_line(tmp_path, capsys, content, expected):
    cap = _side(tmp_path, content)
    with bounded(10), pytest.raises(UserInputError, match=expected):
        capture_io.open_capture(cap)
    rc, err = _run(["beacons", str(cap), "--tle", str(shared_file("tle/starlink_2026-02-23.txt")),
                    "--start", "2026-02-23T06:00:00Z", "--out", str(tmp_path / "o")], capsys)
    assert rc == 2 and len(err) == 1 and expected in err[0], err


def _sigmf(tmp_path, doc_text: bytes):
    (tmp_path / "r.sigmf-data").write_bytes(capture_io.quantize_cu8(_tones(0.5, 0), 1.0).tobytes())
    (tmp_path / "r.sigmf-meta").write_bytes(doc_text)
    return tmp_path / "r.sigmf-meta"


def _good_sigmf_doc() -> dict:
    return {"global": {"core:datatype": "cu8", "core:sample_rate": FS, "core:version": "1.0.0"},
            "captures": [{"core:sample_start": 0, "core:frequency": 1.575e9,
                          "core:datetime": "2026-02-23T06:00:00Z"}], "annotations": []}


def _nested(depth: int):
    value: object = 1.0
    for _ in range(depth):
        value = {"a": value}
    return value


@pytest.mark.parametrize("mutate,expected", [
    (lambda d: b'{"global": ' + b"[" * 100_000 + b"]" * 100_000 + b"}", "nested"),
    (lambda d: json.dumps(dict(d, **{"global": [1, 2]})).encode(), "global"),
    (lambda d: json.dumps(dict(d, captures=[[1]])).encode(), "captures"),
    (lambda d: json.dumps(dict(d, captures={"a": 1})).encode(), "captures"),
    (lambda d: json.dumps(dict(d, **{"global": dict(d["global"], **{"core:sample_rate": _nested(200)})})).encode(),
     "core:sample_rate"),
    (lambda d: json.dumps(dict(d, captures=[dict(d["captures"][0], **{"core:header_bytes": -5})])).encode(),
     "core:header_bytes"),
    (lambda d: json.dumps(dict(d, captures=[dict(d["captures"][0], **{"core:datetime": 5})])).encode(),
     "core:datetime"),
    (lambda d: json.dumps(dict(d, **{"global": dict(d["global"], **{"core:dataset": "x\u0000y"})})).encode(),
     None),
    (lambda d: json.dumps(d).encode("utf-16"), "UTF-8"),
])
def test_broken_sigmf_metadata_is_one_clear_line(tmp_path, capsys, mutate, expected):
    meta = _sigmf(tmp_path, mutate(_good_sigmf_doc()))
    try:
        with bounded(10):
            capture_io.open_capture(meta)
    except UserInputError as exc:
        assert expected is None or expected in str(exc)
        assert len(str(exc)) < 600
    rc, err = _run(["beacons", str(meta), "--tle", str(shared_file("tle/starlink_2026-02-23.txt")),
                    "--out", str(tmp_path / "o")], capsys)
    assert rc in (0, 2) and (rc == 0 or len(err) == 1), err
