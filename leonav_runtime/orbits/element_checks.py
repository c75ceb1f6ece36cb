"""Checks of element files: the size limit and finite decoded TLE fields."""
from __future__ import annotations

from typing import Sequence

import math
import os
import re

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.orbits import tle as _tle

DEFAULT_MAX_ELEMENT_MB = 64.0
MAX_ELEMENT_MB_ENV = "LEONAV_MAX_ELEMENT_MB"


def max_element_bytes() -> int:
    """Largest element file read, bytes: $LEONAV_MAX_ELEMENT_MB megabytes, default 64."""
    text = os.environ.get(MAX_ELEMENT_MB_ENV, "").strip()
    if not text:
        return int(DEFAULT_MAX_ELEMENT_MB * 1e6)
    try:
        mb = float(text)
    except ValueError:
        mb = math.nan
    if not (math.isfinite(mb) and mb > 0):
        raise UserInputError(f"{MAX_ELEMENT_MB_ENV}={text!r}: expected a positive number of megabytes")
    return int(mb * 1e6)


def _too_large(source: str, size: int, limit: int) -> UserInputError:
    return UserInputError(
        f"{source}: {size / 1e6:.1f} MB is more than the element-file limit of {limit / 1e6:g} MB "
        f"(expected a TLE/3LE/OMM file; set {MAX_ELEMENT_MB_ENV} to a larger number of megabytes to read it)")


# Decoded TLE fields that are floats, with where they are written (line, columns).
_TLE_FLOAT_FIELDS = (
    ("ndot_revday2", "mean-motion derivative", 1, "34-43"),
    ("nddot_revday3", "mean-motion second derivative", 1, "45-52"),
    ("bstar_per_earth_radius", "B*", 1, "54-61"),
    ("inclination_deg", "inclination", 2, "9-16"),
    ("raan_deg", "right ascension of the ascending node", 2, "18-25"),
    ("eccentricity", "eccentricity", 2, "27-33"),
    ("arg_perigee_deg", "argument of perigee", 2, "35-42"),
    ("mean_anomaly_deg", "mean anomaly", 2, "44-51"),
    ("mean_motion_revday", "mean motion", 2, "53-63"),
)


def _check_finite(fields: "_tle.TLEFields") -> None:
    """TLEFieldError naming the first field that decoded to NaN or infinity ('nan' passes float())."""
    for attr, label, which, cols in _TLE_FLOAT_FIELDS:
        value = getattr(fields, attr)
        if not math.isfinite(value):
            raise _tle.TLEFieldError(f"field {label} (line {which}, columns {cols}) is {value!r}; "
                                     "expected a finite number", which)


def guess_constellation(names: Sequence[str]) -> str:
    """'starlink' / 'gps' when at least 90 % of the names say so, else 'unknown'."""
    if not names:
        return "unknown"
    upper = [n.upper() for n in names]
    for label, keys in (("starlink", ("STARLINK",)), ("gps", ("GPS", "NAVSTAR"))):
        # one regular-expression search per name: a generator per name cost 11 ms on a day's
        # 9,543 Starlink sets, at every `leonav beacons` start
        found = re.compile("|".join(map(re.escape, keys))).search
        hits = sum(1 for n in upper if found(n))
        if hits >= 0.9 * len(upper):
            return label
    return "unknown"
