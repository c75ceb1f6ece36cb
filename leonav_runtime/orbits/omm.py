"""CCSDS Orbit Mean-Elements Messages (OMM) as CelesTrak serves them: XML, JSON, CSV.

Each record is turned into an SGP4 record with `Satrec.sgp4init` (WGS-72, opsmode 'i',
the constants CelesTrak's elements are fitted with). Field names are the OMM keywords
(`OBJECT_NAME, NORAD_CAT_ID, EPOCH, MEAN_MOTION, ECCENTRICITY, INCLINATION, ...`).

Hostile input: a record that cannot be read (a CSV row the csv module refuses, a JSON
item that is not an object or has arrays/objects as values) is yielded with `problem`
set, so the caller counts it as rejected and goes on. A file whose structure breaks part
way (truncated or corrupted JSON/XML) yields the records before the break and then one
record with `problem` naming the line and column. XML nested deeper than `MAX_XML_DEPTH`
and JSON nested deeper than Python's recursion limit are refused the same way, so no
input can exhaust the stack or make record extraction quadratic.
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
MAX_XML_DEPTH = 64          # CelesTrak's OMM XML is 7 deep (ndm/omm/body/segment/data/meanElements/FIELD)
MAX_NORAD_ID = 999_999_999  # OMM NORAD_CAT_ID has at most 9 digits
MAX_MEAN_MOTION_REVDAY = 100.0  # above the TLE field's range (and any Earth orbit)
_XML_FEED_CHARS = 1 << 20


class OMMRecordError(ValueError):
    """A record is missing a field or has a bad value; the message says which."""


@dataclass(frozen=True)
class OMMRecord:
    """One OMM record with its position in the file (line for CSV, record number otherwise)."""

    fields: dict[str, str]
    line: int
    where: str  # "line 7" or "record 3"
    problem: str | None = None  # why the record cannot be read at all (it is rejected)


def show(text: str, limit: int = 40) -> str:
    """repr() of a field value, shortened: messages stay one readable line whatever the input."""
    text = str(text)
    if len(text) <= limit:
        return repr(text)
    return repr(text[:limit]) + f"... ({len(text)} characters)"


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
    """Yield the raw field dictionaries of an OMM text in format `fmt` (see the module notes)."""
    if fmt == "csv":
        yield from _iter_csv(text)
    elif fmt == "json":
        yield from _iter_json(text)
    elif fmt == "xml":
        yield from _iter_xml(text)
    else:
        raise ValueError(f"unknown OMM format {fmt!r}")


def _iter_csv(text: str) -> Iterator[OMMRecord]:
    line_no = 0

    def lines():
        nonlocal line_no
        for line in io.StringIO(text.lstrip("\ufeff"), newline=""):
            line_no += 1
            yield line

    reader = csv.DictReader(lines())
    while True:
        try:
            row = next(reader)
        except StopIteration:
            return
        except csv.Error as exc:  # e.g. a field over the csv module's 128 KB limit: reject the row, go on
            yield OMMRecord({}, line_no, f"line {line_no}", f"line {line_no}: CSV row cannot be read ({exc})")
            continue
        fields = {k.strip().upper(): (v or "").strip() if isinstance(v, str) else ""
                  for k, v in row.items() if isinstance(k, str)}
        yield OMMRecord(fields, reader.line_num, f"line {reader.line_num}")


def _json_value(key: str, value) -> tuple[str, str | None]:
    if value is None:
        return "", None
    if isinstance(value, (dict, list)):
        kind = "an object" if isinstance(value, dict) else "an array"
        return "", f"field {key[:40]} is {kind}, expected a number or text"
    return str(value), None


def _json_record(item, index: int) -> OMMRecord:
    where = f"record {index}"
    if not isinstance(item, dict):
        return OMMRecord({}, index, where, f"{where} is a JSON {type(item).__name__}, expected an object")
    fields, problem = {}, None
    for key, value in item.items():
        fields[str(key).upper()], bad = _json_value(str(key), value)
        problem = problem or bad
    return OMMRecord(fields, index, where, f"{where}: {problem}" if problem else None)


def _position(text: str, pos: int) -> str:
    line = text.count("\n", 0, pos) + 1
    col = pos - (text.rfind("\n", 0, pos) + 1) + 1
    return f"line {line}, column {col}"


def _iter_json(text: str) -> Iterator[OMMRecord]:
    body = text.lstrip("\ufeff \t\r\n")
    try:
        data = json.loads(body)
    except RecursionError:
        data, whole_failed = None, "nested too deeply"
    except json.JSONDecodeError as exc:
        data, whole_failed = None, f"line {exc.lineno}, column {exc.colno}: {exc.msg}"
    else:
        whole_failed = None
    if whole_failed is None:
        if isinstance(data, dict):
            data = [data]
        if not isinstance(data, list):
            raise OMMRecordError(f"JSON top level is {type(data).__name__}, expected an array of objects")
        for index, item in enumerate(data, start=1):
            yield _json_record(item, index)
        return
    # Not valid as a whole (truncated download, a corrupted byte): read the array item by
    # item so the records before the damage load, then reject the rest once.
    decoder = json.JSONDecoder()
    if not body.startswith("["):
        raise OMMRecordError(f"not valid JSON ({whole_failed})")
    pos, index = 1, 0
    while True:
        while pos < len(body) and body[pos] in " \t\r\n":
            pos += 1
        if pos < len(body) and body[pos] == "]":
            return
        index += 1
        try:
            item, pos = decoder.raw_decode(body, pos)
        except RecursionError:
            reason = "nested too deeply"
        except json.JSONDecodeError as exc:
            reason = f"{_position(body, exc.pos)}: {exc.msg}"
        else:
            yield _json_record(item, index)
            while pos < len(body) and body[pos] in " \t\r\n":
                pos += 1
            if pos < len(body) and body[pos] == ",":
                pos += 1
                continue
            if pos < len(body) and body[pos] == "]":
                return
            reason = f"{_position(body, pos)}: expected ',' or ']' after record {index}"
            index += 1
        yield OMMRecord({}, index, f"record {index}",
                        f"record {index}: not valid JSON ({reason}); the rest of the file is ignored")
        return


def _iter_xml(text: str) -> Iterator[OMMRecord]:
    parser = ET.XMLPullParser(events=("start", "end"))
    depth, index, open_segments = 0, 0, 0
    body = text.lstrip("\ufeff")
    try:
        for offset in range(0, max(len(body), 1), _XML_FEED_CHARS):
            parser.feed(body[offset: offset + _XML_FEED_CHARS])
            for event, el in parser.read_events():
                is_segment = _local(el.tag) == "segment"
                if event == "start":
                    depth += 1
                    open_segments += is_segment
                    if depth > MAX_XML_DEPTH:
                        raise OMMRecordError(f"elements nested deeper than {MAX_XML_DEPTH}")
                    continue
                depth -= 1
                if not is_segment:
                    if open_segments == 0:
                        el.clear()  # outside every record: nothing to keep
                    continue
                open_segments -= 1
                # CelesTrak: <ndm><omm><body><segment><metadata/><data><meanElements/>...; namespaces vary.
                index += 1
                fields = {}
                for leaf in el.iter():
                    if len(leaf) == 0 and leaf.text is not None:
                        fields[_local(leaf.tag).upper()] = leaf.text.strip()
                el.clear()  # records are independent: keep memory flat and a nested segment counted once
                yield OMMRecord(fields, index, f"record {index}")
        parser.close()
    except ET.ParseError as exc:
        line, col = getattr(exc, "position", (0, 0))
        index += 1
        yield OMMRecord({}, index, f"record {index}",
                        f"record {index}: not well-formed at line {line}, column {col + 1} "
                        f"({str(exc).split(':')[0]}); the rest of the file is ignored")
    except OMMRecordError as exc:
        index += 1
        yield OMMRecord({}, index, f"record {index}", f"record {index}: {exc}; the rest of the file is ignored")


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _number(fields: dict[str, str], key: str) -> float:
    text = fields.get(key, "")
    if text == "":
        raise OMMRecordError(f"missing field {key}")
    try:
        value = float(text)
    except ValueError:
        raise OMMRecordError(f"non-numeric field {key}: {show(text)}") from None
    if not math.isfinite(value):
        raise OMMRecordError(f"field {key} is not finite: {show(text)}")
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
    except (ValueError, OverflowError):
        raise OMMRecordError(f"field EPOCH {show(text)} is not YYYY-MM-DDTHH:MM:SS[.ffffff]") from None
    return epoch.replace(tzinfo=_dt.timezone.utc)


def record_to_satrec(fields: dict[str, str]) -> tuple[str, int, _dt.datetime, Satrec]:
    """(name, NORAD id, epoch, Satrec) of one OMM record; raises OMMRecordError."""
    for key in _REQUIRED:
        if fields.get(key, "") == "":
            raise OMMRecordError(f"missing field {key}")
    norad_text = fields["NORAD_CAT_ID"]
    if not (norad_text.isascii() and norad_text.isdigit()):
        raise OMMRecordError(f"non-numeric field NORAD_CAT_ID: {show(norad_text)}")
    if len(norad_text.lstrip("0")) > len(str(MAX_NORAD_ID)) or int(norad_text) > MAX_NORAD_ID:
        raise OMMRecordError(f"field NORAD_CAT_ID {show(norad_text)} is out of range; expected 0..{MAX_NORAD_ID}")
    norad_id = int(norad_text)
    epoch = parse_omm_epoch(fields["EPOCH"])
    ecc = _number(fields, "ECCENTRICITY")
    incl_deg = _number(fields, "INCLINATION")
    n_revday = _number(fields, "MEAN_MOTION")
    if not 0.0 <= ecc < 1.0:
        raise OMMRecordError(f"ECCENTRICITY {ecc} outside 0..1")
    if not 0.0 <= incl_deg <= 180.0:
        raise OMMRecordError(f"INCLINATION {incl_deg} deg outside 0..180")
    if not 0.0 < n_revday <= MAX_MEAN_MOTION_REVDAY:
        raise OMMRecordError(f"MEAN_MOTION {n_revday} rev/day: expected > 0 and <= {MAX_MEAN_MOTION_REVDAY:g}")
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
    name = fields.get("OBJECT_NAME", "").strip()[:80] or str(norad_id)
    return name, norad_id, epoch, satrec
