"""IQ capture readers and writers: RTL-SDR raw cu8, SigMF, raw complex64.

A capture is described by `CaptureInfo` (sample rate, tuned frequency, LNB LO, start
time, sample format) and read with `iter_chunks`, a generator of complex64 blocks, so
memory stays bounded whatever the file length.

Frequency bookkeeping (all Hz): the SDR is tuned to `center_freq_hz` (the IF, e.g.
1.575 GHz); a universal Ku LNB with local oscillator `lnb_lo_hz` (9.75 GHz) sits in front,
so baseband 0 Hz corresponds to the RF frequency `rf_center_hz = center_freq_hz +
lnb_lo_hz` (LO below the signal: the Doppler sign is kept).

Supported formats
- ``cu8``: `rtl_sdr` output, interleaved unsigned 8-bit I,Q with offset 127.5. The file has
  no metadata: give it on the CLI or in a JSON side file ``<capture>.json``.
- ``ci8``: interleaved signed 8-bit I,Q (HackRF style).
- ``cf32``: interleaved little-endian float32 I,Q (numpy complex64), JSON side file / CLI.
- SigMF: ``.sigmf-meta`` + ``.sigmf-data`` with ``core:datatype`` cu8, ci8 or cf32_le,
  ``core:sample_rate``, ``core:frequency`` and ``core:datetime`` in the first capture,
  and the extension fields ``leonav:lnb_lo_hz`` / ``leonav:rf_center_hz`` (global).

Metadata from files is untrusted: side files and .sigmf-meta must be UTF-8 JSON of at
most `MAX_METADATA_BYTES`, with the documented structure (objects and lists where the
formats say so, numbers and ISO times in the fields); sample rates must lie in
[`MIN_SAMPLE_RATE_HZ`, `MAX_SAMPLE_RATE_HZ`] and frequencies within `MAX_FREQ_HZ`.
Anything else is a UserInputError naming the file and field, with the offending value
shortened, never a traceback.
"""
from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import reprlib
from pathlib import Path
from typing import Iterator

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.common.utc import parse_utc  # noqa: F401  (re-exported: callers use capture_io.parse_utc)

DEFAULT_LNB_LO_HZ = 9.75e9
BYTES_PER_SAMPLE = {"cu8": 2, "ci8": 2, "cf32": 8}
_SIGMF_DATATYPES = {"cu8": "cu8", "ci8": "ci8", "cf32_le": "cf32"}
_RAW_SUFFIXES = {".cu8": "cu8", ".bin": "cu8", ".iq": "cu8", ".dat": "cu8", ".raw": "cu8",
                 ".ci8": "ci8", ".cf32": "cf32", ".c64": "cf32", ".complex64": "cf32",
                 ".cfile": "cf32"}
# Largest |I|,|Q| accepted in a cf32 file; larger (or non-finite) values mean the bytes are
# not float32 IQ (e.g. a cu8 capture read as cf32).
_CF32_MAX_ABS = 1e6
MIN_SAMPLE_RATE_HZ = 1e3          # below: not an SDR capture (and STFT bins would be absurd)
MAX_SAMPLE_RATE_HZ = 1e9          # above any SDR this pipeline can read
MAX_FREQ_HZ = 1e11                # tuned frequencies and LNB LOs (Ku band is 10.7-12.75 GHz)
MAX_METADATA_BYTES = 16_000_000   # a side file or .sigmf-meta (SigMF annotations included)

_SHOW = reprlib.Repr()
_SHOW.maxstring = _SHOW.maxother = 40
_SHOW.maxlevel, _SHOW.maxdict, _SHOW.maxlist = 2, 4, 4


def show(value) -> str:
    """Short repr of a metadata value for messages (depth and length limited)."""
    return _SHOW.repr(value)


def _is_file(path: Path) -> bool:
    """Path.is_file() that says False for names the OS refuses (NUL bytes, too long)."""
    try:
        return path.is_file()
    except (OSError, ValueError):
        return False


@dataclasses.dataclass
class CaptureInfo:
    """What is known about one capture file (SI units, UTC)."""

    path: Path                       # file with the samples
    sample_format: str               # cu8 | ci8 | cf32
    sample_rate_hz: float
    center_freq_hz: float            # SDR tuned frequency (IF)
    lnb_lo_hz: float                 # nominal LNB local oscillator (0 if no LNB)
    start_utc: _dt.datetime | None   # time of the first sample
    n_samples: int                   # complete IQ samples in the file
    trailing_bytes: int = 0          # bytes after the last complete sample (ignored, counted)
    header_bytes: int = 0
    source: str = ""                 # where the metadata came from

    @property
    def rf_center_hz(self) -> float:
        """RF frequency that maps to baseband 0 Hz."""
        return self.center_freq_hz + self.lnb_lo_hz

    @property
    def duration_s(self) -> float:
        return self.n_samples / self.sample_rate_hz

    def describe(self) -> dict:
        d = dataclasses.asdict(self)
        d["path"] = str(self.path)
        d["rf_center_hz"] = self.rf_center_hz
        d["duration_s"] = self.duration_s
        return d


def _float(value, where: str, expected: str) -> float:
    if isinstance(value, (dict, list, tuple, bool)) or value is None:
        raise UserInputError(f"{where}: expected {expected}, got {show(value)}")
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):
        raise UserInputError(f"{where}: expected {expected}, got {show(value)}") from None


def _positive(value, where: str) -> float:
    v = _float(value, where, "a positive number")
    if not np.isfinite(v) or v <= 0:
        raise UserInputError(f"{where}: expected a positive number, got {show(value)}")
    return v


def _finite(value, where: str) -> float:
    v = _float(value, where, "a number")
    if not np.isfinite(v):
        raise UserInputError(f"{where}: expected a finite number, got {show(value)}")
    return v


def _sample_rate(value, where: str) -> float:
    v = _positive(value, where)
    if not MIN_SAMPLE_RATE_HZ <= v <= MAX_SAMPLE_RATE_HZ:
        raise UserInputError(f"{where}: {v:g} samples/s is outside {MIN_SAMPLE_RATE_HZ:g}..{MAX_SAMPLE_RATE_HZ:g}; "
                             "expected an SDR sample rate such as 2.4e6")
    return v


def _frequency(value, where: str) -> float:
    v = _positive(value, where)
    if v > MAX_FREQ_HZ:
        raise UserInputError(f"{where}: {v:g} Hz is above {MAX_FREQ_HZ:g} Hz; expected the SDR tuned frequency, "
                             "e.g. 1.575e9")
    return v


def _lnb_lo(value, where: str) -> float:
    v = _finite(value, where)
    if abs(v) > MAX_FREQ_HZ:
        raise UserInputError(f"{where}: {v:g} Hz is beyond {MAX_FREQ_HZ:g} Hz; expected an LNB LO such as 9.75e9")
    return v


def _utc(value, where: str) -> _dt.datetime:
    if not isinstance(value, str) or len(value) > 64:
        raise UserInputError(f"{where}: expected an ISO 8601 UTC time such as 2026-02-23T06:00:00Z, got {show(value)}")
    try:
        return parse_utc(value, where)
    except OverflowError:  # e.g. year 1 with a positive offset: before datetime.min in UTC
        raise UserInputError(f"{where}: {show(value)} is out of the representable range; "
                             "expected an ISO 8601 UTC time such as 2026-02-23T06:00:00Z") from None


def read_json_file(path: Path, what: str):
    """Parse a small UTF-8 JSON metadata file; UserInputError naming `path` for anything else."""
    try:
        size = path.stat().st_size
        if size > MAX_METADATA_BYTES:
            raise UserInputError(f"{path}: {size / 1e6:.1f} MB is larger than the {MAX_METADATA_BYTES / 1e6:g} MB "
                                 f"accepted for {what}")
        with open(path, "rb") as fh:
            raw = fh.read(MAX_METADATA_BYTES + 1)
    except IsADirectoryError:
        raise UserInputError(f"{path}: is a directory, expected {what}") from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise UserInputError(f"{path}: byte {exc.start} is not UTF-8 text; expected {what} in UTF-8 JSON") from None
    try:
        return json.loads(text)
    except RecursionError:
        raise UserInputError(f"{path}: JSON nested too deeply; expected {what}") from None
    except json.JSONDecodeError as exc:
        raise UserInputError(f"{path}: line {exc.lineno}: not valid JSON ({exc.msg}); expected {what}") from None


def _sizes(path: Path, fmt: str, header_bytes: int = 0) -> tuple[int, int]:
    """(complete samples, trailing bytes) of a raw sample file."""
    if not _is_file(path):   # name files of the same stem: `--simulate` writes sim.sigmf-data for sim.cu8
        found = sorted(p.name for p in path.parent.glob(f"{path.name.split('.')[0]}.*") if p != path)
        raise UserInputError(f"{path}: capture data file not found" + (
            f"; found {', '.join(found)} beside it: give that file" if found else ""))
    size = path.stat().st_size - header_bytes
    if size <= 0:
        raise UserInputError(f"{path}: capture file is empty (0 bytes of samples)")
    bps = BYTES_PER_SAMPLE[fmt]
    return size // bps, size % bps


def _check_rf_consistency(center: float, lnb: float, rf_center: float | None, where: str) -> None:
    if rf_center is not None and abs(center + lnb - rf_center) > 1.0:
        raise UserInputError(
            f"{where}: inconsistent metadata: leonav:rf_center_hz={rf_center:.0f} but "
            f"core:frequency + leonav:lnb_lo_hz = {center:.0f} + {lnb:.0f} = {center + lnb:.0f}")


def open_capture(path: str | Path, sample_format: str | None = None, *,
                 sample_rate_hz: float | None = None, center_freq_hz: float | None = None,
                 lnb_lo_hz: float | None = None, start_utc: _dt.datetime | str | None = None) -> CaptureInfo:
    """Describe a capture file. Keyword values override the file's own metadata.

    Raw files (cu8/ci8/cf32) read metadata from a JSON side file ``<path>.json`` with keys
    ``sample_rate_hz, center_freq_hz, lnb_lo_hz, start_utc`` when present; otherwise the
    sample rate and centre frequency must be given. SigMF recordings are recognised by
    the ``.sigmf-meta``/``.sigmf-data`` suffix (either may be given).
    """
    path = Path(path)
    if isinstance(start_utc, str):
        start_utc = parse_utc(start_utc, "--start", require_zone=True)
    name = path.name
    sibling_meta = path.with_suffix(".sigmf-meta")
    if name.endswith(".sigmf-meta") or name.endswith(".sigmf-data") or sample_format == "sigmf":
        info = _open_sigmf(path)
    elif _is_file(sibling_meta) and sample_format is None:
        info = _open_sigmf(sibling_meta, data_path=path)  # e.g. `leonav record`: x.cu8 + x.sigmf-meta
    else:
        info = _open_raw(path, sample_format)
    if sample_rate_hz is not None:
        info.sample_rate_hz = _sample_rate(sample_rate_hz, "--sample-rate")
    if center_freq_hz is not None:
        info.center_freq_hz = _frequency(center_freq_hz, "--center-freq")
    if lnb_lo_hz is not None:
        info.lnb_lo_hz = _lnb_lo(lnb_lo_hz, "--lnb-lo")
    if start_utc is not None:
        info.start_utc = start_utc
    missing = [k for k in ("sample_rate_hz", "center_freq_hz") if getattr(info, k) is None]
    if missing:
        raise UserInputError(
            f"{path}: raw {info.sample_format} capture has no {', '.join(missing)}: give "
            f"--sample-rate/--center-freq or a side file {path.name}.json with those keys")
    return info


def _open_raw(path: Path, sample_format: str | None) -> CaptureInfo:
    fmt = sample_format or _RAW_SUFFIXES.get(path.suffix.lower())
    if fmt is None:
        raise UserInputError(
            f"{path}: cannot tell the sample format from the suffix {path.suffix!r}; expected one of "
            f"{sorted(_RAW_SUFFIXES)} or .sigmf-meta, or give --format cu8|ci8|cf32|sigmf")
    if fmt not in BYTES_PER_SAMPLE:
        raise UserInputError(f"{path}: unknown sample format {fmt!r}; expected cu8, ci8, cf32 or sigmf")
    n, trailing = _sizes(path, fmt)
    meta: dict = {}
    side = path.with_name(path.name + ".json")
    source = "command line"
    if _is_file(side):
        meta = read_json_file(side, "a JSON object with sample_rate_hz, center_freq_hz, ...")
        if not isinstance(meta, dict):
            raise UserInputError(f"{side}: expected a JSON object with sample_rate_hz, center_freq_hz, ...")
        source = str(side)
    sr = _sample_rate(meta["sample_rate_hz"], f"{side}: field sample_rate_hz") if "sample_rate_hz" in meta else None
    fc = _frequency(meta["center_freq_hz"], f"{side}: field center_freq_hz") if "center_freq_hz" in meta else None
    lnb = _lnb_lo(meta.get("lnb_lo_hz", DEFAULT_LNB_LO_HZ), f"{side}: field lnb_lo_hz")
    if fc is not None and "rf_center_hz" in meta:
        _check_rf_consistency(fc, lnb, _finite(meta["rf_center_hz"], f"{side}: field rf_center_hz"), str(side))
    t0 = _utc(meta["start_utc"], f"{side}: field start_utc") if "start_utc" in meta else None
    return CaptureInfo(path, fmt, sr, fc, lnb, t0, n, trailing, 0, source)


def _sigmf_data_path(base: str, meta_path: Path, glob: dict) -> Path:
    """The samples of a recording: `<base>.sigmf-data`, else core:dataset, else `<base>.cu8|ci8|cf32`."""
    candidates = [Path(base + ".sigmf-data")]
    dataset = glob.get("core:dataset")
    if isinstance(dataset, str) and dataset and len(dataset) <= 4096:
        candidates.append(meta_path.parent / dataset)
    candidates += [Path(base + s) for s in (".cu8", ".ci8", ".cf32")]
    for c in candidates:
        if _is_file(c):
            return c
    raise UserInputError(f"{meta_path}: SigMF data file not found (looked for "
                         f"{', '.join(show(c.name) for c in candidates)})")


def _open_sigmf(path: Path, data_path: Path | None = None) -> CaptureInfo:
    import sigmf  # local import: only SigMF users pay for it

    base = str(path)
    for suffix in (".sigmf-meta", ".sigmf-data"):
        if base.endswith(suffix):
            base = base[: -len(suffix)]
    meta_path = Path(base + ".sigmf-meta")
    if not _is_file(meta_path):
        raise UserInputError(f"{meta_path}: SigMF metadata file not found")
    expected = 'a SigMF metadata object {"global": {...}, "captures": [{...}], "annotations": [...]}'
    doc = read_json_file(meta_path, expected)
    if not isinstance(doc, dict):
        raise UserInputError(f"{meta_path}: top level is {type(doc).__name__}; expected {expected}")
    for key, kind in (("global", dict), ("captures", list), ("annotations", list)):
        if key in doc and not isinstance(doc[key], kind):
            raise UserInputError(f"{meta_path}: {key} is {type(doc[key]).__name__}, expected a JSON "
                                 f"{'object' if kind is dict else 'array'}")
    for key in ("captures", "annotations"):
        bad = [i for i, item in enumerate(doc.get(key) or []) if not isinstance(item, dict)]
        if bad:
            raise UserInputError(f"{meta_path}: {key}[{bad[0]}] is {type(doc[key][bad[0]]).__name__}, "
                                 "expected a JSON object")
    glob = doc.get("global", {})
    where = f"{meta_path}: global"
    dtype = glob.get("core:datatype")
    if not isinstance(dtype, str) or dtype not in _SIGMF_DATATYPES:
        raise UserInputError(f"{where} core:datatype={show(dtype)}; expected one of {sorted(_SIGMF_DATATYPES)}")
    if glob.get("core:num_channels", 1) != 1:
        raise UserInputError(f"{where} core:num_channels={show(glob.get('core:num_channels'))}; expected 1")
    if "core:sample_rate" not in glob:
        raise UserInputError(f"{where}: missing core:sample_rate (samples per second)")
    sr = _sample_rate(glob["core:sample_rate"], f"{where} core:sample_rate")
    caps = doc.get("captures") or []
    if not caps:
        raise UserInputError(f"{meta_path}: captures: expected at least one capture segment")
    cap = caps[0]
    if "core:frequency" not in cap:
        raise UserInputError(f"{meta_path}: captures[0]: missing core:frequency (SDR tuned frequency, Hz)")
    fc = _frequency(cap["core:frequency"], f"{meta_path}: captures[0] core:frequency")
    if len(caps) > 1 and any(c.get("core:frequency", fc) != fc for c in caps[1:]):
        raise UserInputError(f"{meta_path}: captures: the tuned frequency changes within the recording; "
                             "expected one frequency (split the recording)")
    t0 = _utc(cap["core:datetime"], f"{meta_path}: captures[0] core:datetime") if "core:datetime" in cap else None
    lnb = _lnb_lo(glob.get("leonav:lnb_lo_hz", DEFAULT_LNB_LO_HZ), f"{where} leonav:lnb_lo_hz")
    rf = glob.get("leonav:rf_center_hz")
    if rf is not None:
        _check_rf_consistency(fc, lnb, _finite(rf, f"{where} leonav:rf_center_hz"), where)
    fmt = _SIGMF_DATATYPES[dtype]
    # the fields leonav reads are checked above (with their names); the schema checks the rest
    try:
        handle = sigmf.SigMFFile(metadata=doc, skip_checksum=True)
        handle.validate()
    except Exception as exc:  # noqa: BLE001 (sigmf raises its own error types for schema violations)
        detail = " ".join(str(exc).split())
        detail = detail if len(detail) <= 200 else detail[:200] + "..."
        raise UserInputError(f"{meta_path}: not a valid SigMF recording: {detail}") from None
    header = cap.get("core:header_bytes", 0)
    if isinstance(header, bool) or not isinstance(header, int) or header < 0:
        raise UserInputError(f"{meta_path}: captures[0] core:header_bytes={show(header)}; expected a byte count >= 0")
    data_path = data_path or _sigmf_data_path(base, meta_path, glob)
    n, trailing = _sizes(data_path, fmt, header)
    return CaptureInfo(data_path, fmt, sr, fc, lnb, t0, n, trailing, header, str(meta_path))


def _to_complex64(raw: np.ndarray, fmt: str) -> np.ndarray:
    """Convert raw bytes of whole samples to complex64 (full scale ~ +/-1 for 8-bit)."""
    if fmt == "cu8":
        f = raw.astype(np.float32)
        f -= 127.5
        f *= 1.0 / 127.5
        return f.view(np.complex64)
    if fmt == "ci8":
        f = raw.view(np.int8).astype(np.float32)
        f *= 1.0 / 128.0
        return f.view(np.complex64)
    return raw.view(np.complex64).copy()


def iter_chunks(info: CaptureInfo, chunk_samples: int = 1 << 20, start_sample: int = 0,
                n_samples: int | None = None) -> Iterator[np.ndarray]:
    """Yield consecutive complex64 blocks of at most `chunk_samples` samples.

    cf32 blocks are checked for non-finite or absurd values, which means the file is not
    float32 IQ (raises UserInputError naming the file and sample index).
    """
    bps = BYTES_PER_SAMPLE[info.sample_format]
    stop = info.n_samples if n_samples is None else min(info.n_samples, start_sample + n_samples)
    with open(info.path, "rb") as fh:
        fh.seek(info.header_bytes + start_sample * bps)
        pos = start_sample
        while pos < stop:
            n = min(chunk_samples, stop - pos)
            raw = np.frombuffer(fh.read(n * bps), dtype=np.uint8)
            if raw.size < n * bps:  # the file shrank while reading
                raise UserInputError(f"{info.path}: truncated while reading at sample {pos}")
            block = _to_complex64(raw, info.sample_format)
            if info.sample_format == "cf32":
                bad = ~np.isfinite(block) | (np.abs(block.view(np.float32)).reshape(-1, 2).max(axis=1) > _CF32_MAX_ABS)
                if bad.any():
                    i = pos + int(np.argmax(bad))
                    raise UserInputError(
                        f"{info.path}: sample {i} is not a plausible float32 IQ value "
                        f"({block[i - pos]!r}); is the file really cf32 (complex64)? try --format cu8")
            yield block
            pos += n


def read_all(info: CaptureInfo) -> np.ndarray:
    """Whole capture as one complex64 array (for small files and tests)."""
    blocks = list(iter_chunks(info))
    return np.concatenate(blocks) if blocks else np.zeros(0, np.complex64)


# writers (synthetic captures, tests) live in capture_write; re-exported for callers of capture_io
from leonav_runtime.beacons.capture_write import quantize_cu8, write_side_json, write_sigmf_meta  # noqa: E402,F401
