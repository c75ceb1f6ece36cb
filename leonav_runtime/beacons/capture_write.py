"""Writers of IQ captures: RTL-SDR uint8 quantization, the JSON side file and SigMF metadata
(the formats `capture_io.open_capture` reads)."""
from __future__ import annotations

import datetime as _dt
import json
from pathlib import Path

import numpy as np


def quantize_cu8(iq: np.ndarray, full_scale: float, rng: np.random.Generator | None = None) -> np.ndarray:
    """Quantize complex samples to interleaved uint8 as an RTL-SDR does.

    `full_scale` is the amplitude that maps to the ADC limits (+/-127.5 codes); values
    beyond it clip. Rounding is to the nearest code (value + 127.5).
    """
    inter = np.empty(2 * iq.size, np.float32)
    inter[0::2] = iq.real
    inter[1::2] = iq.imag
    inter *= 127.5 / full_scale
    inter += 127.5
    np.clip(np.rint(inter), 0, 255, out=inter)
    return inter.astype(np.uint8)


def write_side_json(path: str | Path, sample_rate_hz: float, center_freq_hz: float, lnb_lo_hz: float,
                    start_utc: _dt.datetime | None, extra: dict | None = None) -> Path:
    """Write the JSON side file read by `open_capture` for raw captures."""
    side = Path(str(path) + ".json")
    meta = {"sample_rate_hz": sample_rate_hz, "center_freq_hz": center_freq_hz,
            "lnb_lo_hz": lnb_lo_hz, "rf_center_hz": center_freq_hz + lnb_lo_hz}
    if start_utc is not None:
        meta["start_utc"] = start_utc.isoformat().replace("+00:00", "Z")
    meta.update(extra or {})
    side.write_text(json.dumps(meta, indent=2) + "\n")
    return side


def write_sigmf_meta(base: str | Path, datatype: str, sample_rate_hz: float, center_freq_hz: float,
                     lnb_lo_hz: float, start_utc: _dt.datetime | None, description: str = "",
                     extra: dict | None = None) -> Path:
    """Write `<base>.sigmf-meta` for an existing `<base>.sigmf-data` (validated by sigmf)."""
    import sigmf

    base = Path(base)
    glob = {
        "core:datatype": datatype,
        "core:sample_rate": float(sample_rate_hz),
        "core:version": sigmf.__specification__,
        "core:description": description,
        "core:recorder": "leonav",
        "leonav:lnb_lo_hz": float(lnb_lo_hz),
        "leonav:rf_center_hz": float(center_freq_hz + lnb_lo_hz),
        "core:extensions": [{"name": "leonav", "version": "0.1.0", "optional": True}],
    }
    for k, v in (extra or {}).items():
        glob[f"leonav:{k}"] = v
    cap = {"core:sample_start": 0, "core:frequency": float(center_freq_hz)}
    if start_utc is not None:
        cap["core:datetime"] = start_utc.astimezone(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%fZ")
    doc = {"global": glob, "captures": [cap], "annotations": []}
    sigmf.SigMFFile(metadata=doc, skip_checksum=True).validate()
    meta_path = Path(str(base) + ".sigmf-meta")
    meta_path.write_text(json.dumps(doc, indent=2) + "\n")
    return meta_path
