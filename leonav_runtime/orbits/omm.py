"""CCSDS Orbit Mean-Elements Messages (OMM) as CelesTrak serves them: XML, JSON, CSV.

Each record is turned into an SGP4 record with `Satrec.sgp4init` (WGS-72, opsmode 'i',
the constants CelesTrak's elements are fitted with). Field names are the OMM keywords
(`OBJECT_NAME, NORAD_CAT_ID, EPOCH, MEAN_MOTION, ECCENTRICITY, INCLINATION, ...`).
"""
from __future__ import annotations

import csv
import datetime as _dt
import io
import json
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Iterator

from sgp4.api import WGS72, Satrec

_EPOCH_1949 = _dt.datetime(1949, 12, 31, tzinfo=_dt.timezone.utc)  # sgp4init's day zero
_REQUIRED = (
    "NORAD_CAT_ID", "EPOCH", "MEAN_MOTION", "ECCENTRICITY", "INCLINATION", "RA_OF_ASC_NODE",
    "ARG_OF_PERICENTER", "MEAN_ANOMALY", "BSTAR", "MEAN_MOTION_DOT", "MEAN_MOTION_DDOT",
)
_DEG = math.pi / 180.0
_MIN_PER_DAY = 1440.0


class OMMRecordError(ValueError):
    """A record is missing a field or has a bad value; the message says which."""


@dataclass(frozen=True)
class OMMRecord:
    """One OMM record with its position in the file (line for CSV, record number otherwise)."""

    fields: dict[str, str]
    line: int
    where: str  # "line 7" or "record 3"


def detect_omm_format(text: str) -> str | None:
    """'xml', 'json', 'csv' or None (not OMM: treat as TLE text)."""
    head = text.lstrip("\ufeff \t\r\n")[:4096]
    if head.startswith("<") and ("<omm" in head.lower() or "<ndm" in head.lower()):
        return "xml"  # other markup (an HTML error page) falls through to TLE and is rejected
    if head.startswith("[") or head.startswith("{"):
        return "json"
    first_line = head.splitlines()[0] if head else ""
    if "," in first_line and ("NORAD_CAT_ID" in first_line.upper() or "OBJECT_NAME" in first_line.upper()):
        return "csv"
    return None


def iter_records(text: str, fmt: str) -> Iterator[OMMRecord]:
    """Yield the raw field dictionaries of an OMM text in format `fmt`."""
    if fmt == "csv":
        reader = csv.DictReader(io.StringIO(text.lstrip("\ufeff")))
        for row in reader:
            fields = {k.strip().upper(): (v or "").strip() for k, v in row.items() if k is not None}
            yield OMMRecord(fields, reader.line_num, f"line {reader.line_num}")
    elif fmt == "json":
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise OMMRecordError(f"not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})") from None
        if isinstance(data, dict):
            data = [data]
        for index, item in enumerate(data, start=1):
            if not isinstance(item, dict):
                raise OMMRecordError(f"JSON record {index} is not an object")
            yield OMMRecord({k.upper(): "" if v is None else str(v) for k, v in item.items()},
                            index, f"record {index}")
    elif fmt == "xml":
        try:
            root = ET.fromstring(text.lstrip("\ufeff"))
        except ET.ParseError as exc:
            raise OMMRecordError(f"not valid XML ({exc})") from None
        # CelesTrak: <ndm><omm><body><segment><metadata/><data><meanElements/>...; namespaces vary.
        segments = [el for el in root.iter() if _local(el.tag) == "segment"]
        for index, segment in enumerate(segments, start=1):
            fields = {}
            for el in segment.iter():
                if len(el) == 0 and el.text is not None:
                    fields[_local(el.tag).upper()] = el.text.strip()
            yield OMMRecord(fields, index, f"record {index}")
    else:
        raise ValueError(f"unknown OMM format {fmt!r}")


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _number(fields: dict[str, str], key: str) -> float:
    text = fields.get(key, "")
    if text == "":
        raise OMMRecordError(f"missing field {key}")
    try:
        value = float(text)
    except ValueError:
        raise OMMRecordError(f"non-numeric field {key}: {text!r}") from None
    if not math.isfinite(value):
        raise OMMRecordError(f"field {key} is not finite: {text!r}")
    return value


def parse_omm_epoch(text: str) -> _dt.datetime:
    """OMM EPOCH 'YYYY-MM-DDTHH:MM:SS[.ffffff]' (UTC) as a tz-aware datetime."""
    text = text.strip().rstrip("Z")
    try:
        if "." in text:
            base, frac = text.split(".", 1)
            epoch = _dt.datetime.strptime(base, "%Y-%m-%dT%H:%M:%S")
            epoch += _dt.timedelta(seconds=float("0." + frac))
        else:
            epoch = _dt.datetime.strptime(text, "%Y-%m-%dT%H:%M:%S")
    except ValueError:
        raise OMMRecordError(f"field EPOCH {text!r} is not YYYY-MM-DDTHH:MM:SS[.ffffff]") from None
    return epoch.replace(tzinfo=_dt.timezone.utc)


def record_to_satrec(fields: dict[str, str]) -> tuple[str, int, _dt.datetime, Satrec]:
    """(name, NORAD id, epoch, Satrec) of one OMM record; raises OMMRecordError."""
    for key in _REQUIRED:
        if fields.get(key, "") == "":
            raise OMMRecordError(f"missing field {key}")
    norad_text = fields["NORAD_CAT_ID"]
    if not norad_text.isdigit():
        raise OMMRecordError(f"non-numeric field NORAD_CAT_ID: {norad_text!r}")
    norad_id = int(norad_text)
    epoch = parse_omm_epoch(fields["EPOCH"])
    ecc = _number(fields, "ECCENTRICITY")
    incl_deg = _number(fields, "INCLINATION")
    n_revday = _number(fields, "MEAN_MOTION")
    if not 0.0 <= ecc < 1.0:
        raise OMMRecordError(f"ECCENTRICITY {ecc} outside 0..1")
    if not 0.0 <= incl_deg <= 180.0:
        raise OMMRecordError(f"INCLINATION {incl_deg} deg outside 0..180")
    if n_revday <= 0.0:
        raise OMMRecordError(f"MEAN_MOTION {n_revday} rev/day must be > 0")
    epoch_days = (epoch - _EPOCH_1949) / _dt.timedelta(days=1)
    rad_per_min = 2.0 * math.pi / _MIN_PER_DAY
    satrec = Satrec()
    satrec.sgp4init(
        WGS72, "i", norad_id if norad_id <= 339999 else 0, epoch_days,
        _number(fields, "BSTAR"),
        _number(fields, "MEAN_MOTION_DOT") * rad_per_min / _MIN_PER_DAY,  # rev/day^2 -> rad/min^2
        _number(fields, "MEAN_MOTION_DDOT") * rad_per_min / _MIN_PER_DAY**2,  # rev/day^3 -> rad/min^3
        ecc,
        _number(fields, "ARG_OF_PERICENTER") * _DEG,
        incl_deg * _DEG,
        _number(fields, "MEAN_ANOMALY") * _DEG,
        n_revday * rad_per_min,
        _number(fields, "RA_OF_ASC_NODE") * _DEG,
    )
    name = fields.get("OBJECT_NAME", "").strip() or str(norad_id)
    return name, norad_id, epoch, satrec
