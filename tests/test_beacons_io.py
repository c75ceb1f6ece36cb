"""Capture readers: formats, chunking, and every kind of bad input gives a clear error."""
from __future__ import annotations

import datetime as dt
import json

import numpy as np
import pytest

from leonav_runtime.beacons import capture_io
from leonav_runtime.common.errors import UserInputError

T0 = dt.datetime(2026, 2, 23, 6, 0, tzinfo=dt.timezone.utc)


def _iq(n, seed=0):
    rng = np.random.default_rng(seed)
    return (0.15 * (rng.standard_normal(n) + 1j * rng.standard_normal(n))).astype(np.complex64)


def test_cu8_roundtrip_and_chunks(tmp_path):
    x = _iq(10_001)
    path = tmp_path / "cap.cu8"
    path.write_bytes(capture_io.quantize_cu8(x, 1.0).tobytes())
    capture_io.write_side_json(path, 2.4e6, 1.575e9, 9.75e9, T0)
    info = capture_io.open_capture(path)
    assert (info.n_samples, info.sample_rate_hz, info.rf_center_hz, info.start_utc) == (10_001, 2.4e6, 11.325e9, T0)
    chunks = list(capture_io.iter_chunks(info, chunk_samples=4096))
    assert [c.size for c in chunks] == [4096, 4096, 1809]
    y = np.concatenate(chunks)
    # 8-bit quantization: error at most half a code (1/255 of full scale) per component
    assert np.max(np.abs(y.real - x.real)) <= 0.5 / 127.5 + 1e-6
    assert np.max(np.abs(y.imag - x.imag)) <= 0.5 / 127.5 + 1e-6


def test_rtl_sdr_offset_is_127_5(tmp_path):
    path = tmp_path / "c.cu8"
    path.write_bytes(bytes([0, 255, 127, 128]))
    y = capture_io.read_all(capture_io.open_capture(path, sample_rate_hz=1e6, center_freq_hz=1.575e9))
    np.testing.assert_allclose(y, [-1 + 1j, -0.5 / 127.5 + 0.5j / 127.5], atol=1e-7)


def test_odd_byte_count_is_counted_not_crashed(tmp_path):
    path = tmp_path / "odd.cu8"
    path.write_bytes(bytes(range(11)))
    info = capture_io.open_capture(path, sample_rate_hz=1e6, center_freq_hz=1.575e9)
    assert (info.n_samples, info.trailing_bytes) == (5, 1)
    assert capture_io.read_all(info).size == 5


def test_truncated_cf32_counts_trailing_bytes(tmp_path):
    path = tmp_path / "t.cf32"
    path.write_bytes(_iq(100).tobytes()[:-3])
    info = capture_io.open_capture(path, sample_rate_hz=1e6, center_freq_hz=1.575e9)
    assert (info.n_samples, info.trailing_bytes) == (99, 5)


def test_cu8_bytes_read_as_cf32_is_rejected(tmp_path):
    path = tmp_path / "wrong.cf32"
    path.write_bytes(np.random.default_rng(1).integers(0, 256, 80_000, dtype=np.uint8).tobytes())
    info = capture_io.open_capture(path, sample_rate_hz=1e6, center_freq_hz=1.575e9)
    with pytest.raises(UserInputError, match="cf32"):
        capture_io.read_all(info)


@pytest.mark.parametrize("content, match", [(b"", "empty"), (None, "not found")])
def test_empty_or_missing_file(tmp_path, content, match):
    path = tmp_path / "e.cu8"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(UserInputError, match=match):
        capture_io.open_capture(path, sample_rate_hz=1e6, center_freq_hz=1.575e9)


def test_raw_without_metadata_and_unknown_suffix(tmp_path):
    path = tmp_path / "x.cu8"
    path.write_bytes(bytes(100))
    with pytest.raises(UserInputError, match="sample_rate_hz"):
        capture_io.open_capture(path)
    other = tmp_path / "x.wav"
    other.write_bytes(bytes(100))
    with pytest.raises(UserInputError, match="--format"):
        capture_io.open_capture(other)
    bad_json = tmp_path / "x.cu8.json"
    bad_json.write_text('{"sample_rate_hz": 1e6,\n "center_freq_hz": }')
    with pytest.raises(UserInputError, match="line 2"):
        capture_io.open_capture(path)
    bad_json.write_text(json.dumps({"sample_rate_hz": -5, "center_freq_hz": 1.575e9}))
    with pytest.raises(UserInputError, match="sample_rate_hz"):
        capture_io.open_capture(path)


def _sigmf(tmp_path, **glob_over):
    base = tmp_path / "rec"
    (tmp_path / "rec.sigmf-data").write_bytes(capture_io.quantize_cu8(_iq(2000), 1.0).tobytes())
    capture_io.write_sigmf_meta(base, "cu8", 2.4e6, 1.575e9, 9.75e9, T0)
    meta_path = tmp_path / "rec.sigmf-meta"
    doc = json.loads(meta_path.read_text())
    for k, v in glob_over.items():
        if v is None:
            doc["global"].pop(k, None)
            doc["captures"][0].pop(k, None)
        else:
            doc["global"][k] = v
    meta_path.write_text(json.dumps(doc))
    return meta_path


def test_sigmf_reads_metadata(tmp_path):
    info = capture_io.open_capture(_sigmf(tmp_path))
    assert (info.sample_format, info.n_samples, info.center_freq_hz, info.lnb_lo_hz, info.start_utc) == \
        ("cu8", 2000, 1.575e9, 9.75e9, T0)
    # the data file name works too
    assert capture_io.open_capture(tmp_path / "rec.sigmf-data").n_samples == 2000


@pytest.mark.parametrize("override, match", [
    ({"core:sample_rate": None}, "sample_rate"),
    ({"core:datatype": "ci16_le"}, "core:datatype"),
    ({"leonav:rf_center_hz": 11.0e9}, "inconsistent"),
    ({"core:frequency": None}, "core:frequency"),
])
def test_sigmf_bad_metadata(tmp_path, override, match):
    with pytest.raises(UserInputError, match=match):
        capture_io.open_capture(_sigmf(tmp_path, **override))


def test_sigmf_missing_datetime_leaves_start_unknown(tmp_path):
    info = capture_io.open_capture(_sigmf(tmp_path, **{"core:datetime": None}))
    assert info.start_utc is None
    assert capture_io.open_capture(_sigmf(tmp_path, **{"core:datetime": None}), start_utc="2026-02-23T06:00:00Z").start_utc == T0


def test_record_layout_cu8_with_sibling_sigmf_meta(tmp_path):
    """`leonav record` writes x.cu8 + x.sigmf-meta; both names open the recording."""
    _sigmf(tmp_path)
    (tmp_path / "rec.sigmf-data").rename(tmp_path / "rec.cu8")
    assert capture_io.open_capture(tmp_path / "rec.cu8").start_utc == T0
    assert capture_io.open_capture(tmp_path / "rec.sigmf-meta").path.name == "rec.cu8"
