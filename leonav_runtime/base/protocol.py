"""The differential-corrections line protocol of `leonav base` (version 1; docs/corrections.md).

ASCII text, one record per line ending in LF (CR LF accepted), fields separated by one or more
spaces, each line closed by `*hh`: two hex digits, the XOR of every byte before the `*` (as in
NMEA 0183), so a line damaged in transit is refused instead of read as other numbers.

    LNVC 1 HDR <lat_deg> <lon_deg> <h_m> UTC*hh
    LNVC 1 COR <constellation> <norad_id> <observable> <t_utc_s> <value> <unit> <sigma>*hh
    LNVC 1 HB <t_utc_s>*hh

- HDR: sent first on every connection: the base's known position (WGS84 geodetic, deg, deg,
  ellipsoidal m) and the time scale of every time field (UTC: seconds since 1970-01-01 UTC,
  POSIX count, no leap seconds, as everywhere in leonav).
- COR: one correction: the base's measured value minus the value predicted from the element
  set at the base's known position, for one satellite (constellation name as in the element
  sets: `starlink`, NORAD id) and observable (`doppler_rate` in Hz/s, `doppler` in Hz), at the
  base's measurement time t_utc_s; sigma (same unit, > 0) is its 1-sigma.
- HB: a heartbeat with the base's clock at sending, once a second whether or not there are
  corrections: a connection that stays open but stops carrying heartbeats is a stopped stream.

`parse_line` returns a `Correction`, `Header`, `Heartbeat` or raises `LineError` with one reason.
"""
from __future__ import annotations

import dataclasses
import math

MAGIC = "LNVC"
VERSION = "1"
UNITS = {"doppler_rate": "Hz/s", "doppler": "Hz"}
"""Observables a correction may carry, and the unit each must be given in."""
MAX_LINE_BYTES = 256


class LineError(ValueError):
    """A line that is not a valid record; the message is the one reason (no line number)."""


@dataclasses.dataclass(frozen=True)
class Correction:
    """One correction: t_utc_s (s, UTC POSIX), value and sigma in the observable's unit."""

    constellation: str
    norad_id: int
    observable: str
    t_utc_s: float
    value: float
    sigma: float


@dataclasses.dataclass(frozen=True)
class Header:
    lat_deg: float
    lon_deg: float
    h_m: float
    time_scale: str = "UTC"


@dataclasses.dataclass(frozen=True)
class Heartbeat:
    t_utc_s: float


def checksum(body: str) -> str:
    """Two upper-case hex digits: the XOR of the bytes of `body`."""
    x = 0
    for b in body.encode("ascii", "replace"):
        x ^= b
    return f"{x:02X}"


def _seal(body: str) -> str:
    return f"{body}*{checksum(body)}\n"


def header_line(lat_deg: float, lon_deg: float, h_m: float) -> str:
    """The HDR line (with its LF) of a base at (lat deg, lon deg, h m)."""
    return _seal(f"{MAGIC} {VERSION} HDR {lat_deg:.8f} {lon_deg:.8f} {h_m:.3f} UTC")


def heartbeat_line(t_utc_s: float) -> str:
    return _seal(f"{MAGIC} {VERSION} HB {t_utc_s:.3f}")


def correction_line(c: Correction) -> str:
    """The COR line (with its LF) of `c`; the unit is the observable's (`UNITS`)."""
    return _seal(f"{MAGIC} {VERSION} COR {c.constellation} {c.norad_id:d} {c.observable} {c.t_utc_s:.3f} "
                 f"{c.value:.5f} {UNITS[c.observable]} {c.sigma:.5f}")


def _number(text: str, name: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise LineError(f"{name} {text!r} is not a number") from None
    if not math.isfinite(v):
        raise LineError(f"{name} {text!r} is not finite")
    return v


def parse_line(raw: bytes | str) -> Correction | Header | Heartbeat:
    """One line (with or without its line end) -> its record; `LineError` names what is wrong."""
    if isinstance(raw, bytes):
        if len(raw) > MAX_LINE_BYTES:
            raise LineError(f"line of {len(raw)} bytes: expected at most {MAX_LINE_BYTES}")
        try:
            raw = raw.decode("ascii")
        except UnicodeDecodeError:
            raise LineError("non-ASCII bytes") from None
    line = raw.rstrip("\r\n")
    body, star, hh = line.rpartition("*")
    if not star:
        raise LineError("no '*hh' checksum at the end")
    if hh.upper() != checksum(body):
        raise LineError(f"checksum {hh!r}: expected {checksum(body)} (line damaged)")
    f = body.split()
    if len(f) < 3 or f[0] != MAGIC:
        raise LineError(f"starts {' '.join(f[:1])!r}: expected '{MAGIC} {VERSION} HDR|COR|HB ...'")
    if f[1] != VERSION:
        raise LineError(f"protocol version {f[1]!r}: expected {VERSION}")
    kind, rest = f[2], f[3:]
    if kind == "COR":
        if len(rest) != 7:
            raise LineError(f"COR with {len(rest)} fields: expected 7 (constellation norad_id observable t_utc_s "
                            f"value unit sigma)")
        const, sat, obs, t, value, unit, sigma = rest
        if obs not in UNITS:
            raise LineError(f"observable {obs!r}: expected one of {', '.join(UNITS)}")
        if unit != UNITS[obs]:
            raise LineError(f"unit {unit!r} for {obs}: expected {UNITS[obs]}")
        if not sat.isdigit() or not 0 < int(sat) < 10_000_000:
            raise LineError(f"norad_id {sat!r}: expected a positive integer")
        s = _number(sigma, "sigma")
        if s <= 0:
            raise LineError(f"sigma {sigma!r}: expected > 0")
        return Correction(const.lower(), int(sat), obs, _number(t, "t_utc_s"), _number(value, "value"), s)
    if kind == "HB":
        if len(rest) != 1:
            raise LineError(f"HB with {len(rest)} fields: expected 1 (t_utc_s)")
        return Heartbeat(_number(rest[0], "t_utc_s"))
    if kind == "HDR":
        if len(rest) != 4 or rest[3] != "UTC":
            raise LineError("HDR: expected 'lat_deg lon_deg h_m UTC'")
        lat, lon, h = (_number(v, n) for v, n in zip(rest, ("lat_deg", "lon_deg", "h_m")))
        if not (-90 <= lat <= 90 and -180 <= lon <= 360):
            raise LineError(f"HDR position {lat}, {lon}: expected latitude -90..90, longitude -180..360")
        return Header(lat, lon, h)
    raise LineError(f"record type {kind!r}: expected HDR, COR or HB")
