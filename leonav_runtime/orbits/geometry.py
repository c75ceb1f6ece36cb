"""WGS84 geometry in NumPy: geodetic <-> ECEF, local ENU frames, az/el/range, visibility, DOP.

Everything is vectorized over leading axes, so one call handles thousands of satellites
at many epochs. Units are SI (m, rad); frames are in the names:

- ECEF: Earth-centred Earth-fixed (WGS84 / ITRF-like), metres.
- ENU: local East-North-Up at a reference point, metres.
- Azimuth is measured from North towards East (clockwise seen from above), in [0, 2*pi).
- Elevation is measured from the local horizon (the plane normal to the WGS84 ellipsoid
  normal, i.e. the geodetic "up"), in [-pi/2, pi/2].

The navigation filter's symbolic ENU model lives in `models/`; this module is the NumPy
twin used for sky plots, visibility counts and scenario set-up, where the numbers of
satellites are large and no derivatives are needed.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gen.constants import GNSS_MASK_DEG, STARLINK_MASK_DEG, WGS84_A_M, WGS84_E2


# Elevation masks used by the paper (Sec. II): 10 deg for GPS (common GNSS practice),
# 28 deg for Starlink (what Starlink user terminals use). Unknown constellations get the
# GNSS value. Radians.
ELEVATION_MASK_DEFAULTS_RAD: dict[str, float] = {
    "gps": math.radians(GNSS_MASK_DEG),
    "starlink": math.radians(STARLINK_MASK_DEG),
    "unknown": math.radians(GNSS_MASK_DEG),
}


def default_mask_rad(constellation: str) -> float:
    """Default elevation mask (rad) for a constellation name (`gps`, `starlink`, other)."""
    return ELEVATION_MASK_DEFAULTS_RAD.get(constellation.lower(), ELEVATION_MASK_DEFAULTS_RAD["unknown"])


def geodetic_to_ecef(lat_rad, lon_rad, h_m) -> np.ndarray:
    """WGS84 geodetic latitude/longitude (rad) and ellipsoidal height (m) -> ECEF (m).

    Inputs broadcast against each other; the result has shape `broadcast + (3,)`.
    """
    lat = np.asarray(lat_rad, dtype=float)
    lon = np.asarray(lon_rad, dtype=float)
    h = np.asarray(h_m, dtype=float)
    sin_lat = np.sin(lat)
    cos_lat = np.cos(lat)
    n = WGS84_A_M / np.sqrt(1.0 - WGS84_E2 * sin_lat**2)  # prime-vertical radius of curvature
    x = (n + h) * cos_lat * np.cos(lon)
    y = (n + h) * cos_lat * np.sin(lon)
    z = (n * (1.0 - WGS84_E2) + h) * sin_lat
    x, y, z = np.broadcast_arrays(x, y, z)
    return np.stack([x, y, z], axis=-1)


def ecef_to_geodetic(r_ecef_m) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ECEF position(s) `(..., 3)` in m -> WGS84 (lat_rad, lon_rad, h_m), each `(...)`.

    Fixed-point iteration on the geodetic latitude with the height written as
    `h = p cos(lat) + z sin(lat) - a sqrt(1 - e^2 sin^2 lat)`, which stays well conditioned
    at the poles (no division by cos(lat)). The contraction factor is about e^2, so a few
    iterations reach far below a millimetre from the Earth's surface out to GNSS orbits.
    Undefined only at the Earth's centre.
    """
    r = np.asarray(r_ecef_m, dtype=float)
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    p = np.hypot(x, y)
    lon = np.arctan2(y, x)
    lat = np.arctan2(z, p * (1.0 - WGS84_E2))  # exact for h = 0
    for _ in range(10):
        sin_lat = np.sin(lat)
        n = WGS84_A_M / np.sqrt(1.0 - WGS84_E2 * sin_lat**2)
        h = p * np.cos(lat) + z * sin_lat - WGS84_A_M * np.sqrt(1.0 - WGS84_E2 * sin_lat**2)
        lat_new = np.arctan2(z, p * (1.0 - WGS84_E2 * n / (n + h)))
        converged = np.all(np.abs(lat_new - lat) < 1e-14)
        lat = lat_new
        if converged:
            break
    sin_lat = np.sin(lat)
    h = p * np.cos(lat) + z * sin_lat - WGS84_A_M * np.sqrt(1.0 - WGS84_E2 * sin_lat**2)
    return lat, lon, h


def _enu_axes_in_ecef(lat_rad, lon_rad) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit East, North, Up vectors expressed in ECEF, each `(..., 3)`."""
    lat = np.asarray(lat_rad, dtype=float)
    lon = np.asarray(lon_rad, dtype=float)
    sl, cl = np.sin(lat), np.cos(lat)
    so, co = np.sin(lon), np.cos(lon)
    sl, cl, so, co = np.broadcast_arrays(sl, cl, so, co)
    east = np.stack([-so, co, np.zeros_like(so)], axis=-1)
    north = np.stack([-sl * co, -sl * so, cl], axis=-1)
    up = np.stack([cl * co, cl * so, sl], axis=-1)
    return east, north, up


def C_enu_ecef(lat_rad, lon_rad) -> np.ndarray:
    """Rotation matrix `(..., 3, 3)` taking ECEF vectors to ENU: `v_enu = C_enu_ecef @ v_ecef`.

    Rows are the East, North and Up unit vectors of the geodetic point expressed in ECEF.
    Its transpose takes ENU vectors to ECEF.
    """
    east, north, up = _enu_axes_in_ecef(lat_rad, lon_rad)
    return np.stack([east, north, up], axis=-2)


def ecef_to_enu(r_ecef_m, r0_ecef_m, lat0_rad, lon0_rad) -> np.ndarray:
    """ECEF position(s) `(..., 3)` -> ENU coordinates (m) relative to origin `r0_ecef_m`.

    `lat0_rad`, `lon0_rad` are the geodetic coordinates of the origin (they define the
    axes; passing them avoids recomputing them from `r0_ecef_m`).
    """
    d = np.asarray(r_ecef_m, dtype=float) - np.asarray(r0_ecef_m, dtype=float)
    east, north, up = _enu_axes_in_ecef(lat0_rad, lon0_rad)
    return np.stack([np.sum(d * east, -1), np.sum(d * north, -1), np.sum(d * up, -1)], axis=-1)


def enu_to_ecef(p_enu_m, r0_ecef_m, lat0_rad, lon0_rad) -> np.ndarray:
    """ENU coordinates (m) at origin `r0_ecef_m` (geodetic lat0/lon0) -> ECEF position(s)."""
    p = np.asarray(p_enu_m, dtype=float)
    east, north, up = _enu_axes_in_ecef(lat0_rad, lon0_rad)
    return (
        np.asarray(r0_ecef_m, dtype=float)
        + p[..., 0:1] * east
        + p[..., 1:2] * north
        + p[..., 2:3] * up
    )


def az_el_range(r_sat_ecef_m, r_rx_ecef_m, lat_rad, lon_rad) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Azimuth, elevation (rad) and range (m) of satellites seen from a receiver.

    `r_sat_ecef_m (..., 3)` and `r_rx_ecef_m (..., 3)` broadcast (e.g. satellites
    `(nsat, nt, 3)` against one receiver `(3,)`); `lat_rad`, `lon_rad` are the receiver's
    geodetic coordinates (broadcast against the leading axes). Both positions must be in
    the same Earth-fixed frame at the same instant (no light-time, no refraction).
    Azimuth counts from North towards East in [0, 2*pi); elevation from the local
    horizon.
    """
    d = np.asarray(r_sat_ecef_m, dtype=float) - np.asarray(r_rx_ecef_m, dtype=float)
    east, north, up = _enu_axes_in_ecef(lat_rad, lon_rad)
    e = np.sum(d * east, -1)
    n = np.sum(d * north, -1)
    u = np.sum(d * up, -1)
    horizontal = np.hypot(e, n)
    rng = np.sqrt(horizontal**2 + u**2)
    az = np.arctan2(e, n)
    # Shift (-pi, 0) up; a tiny negative angle must become 0, not round to 2*pi.
    az = np.where(az < 0.0, az + 2.0 * np.pi, az)
    az = np.where(az >= 2.0 * np.pi, 0.0, az)
    el = np.arctan2(u, horizontal)
    return az, el, rng


def visible_mask(el_rad, mask_rad) -> np.ndarray:
    """Boolean array: elevation at or above the mask (both rad, broadcast). NaN -> False."""
    el = np.asarray(el_rad, dtype=float)
    with np.errstate(invalid="ignore"):
        return el >= np.asarray(mask_rad, dtype=float)


def line_of_sight_enu(az_rad, el_rad) -> np.ndarray:
    """Unit vector(s) `(..., 3)` in ENU from the receiver towards the satellite."""
    az = np.asarray(az_rad, dtype=float)
    el = np.asarray(el_rad, dtype=float)
    return np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=-1)


DOP_KEYS = ("gdop", "pdop", "hdop", "vdop", "tdop")


def dop(az_rad, el_rad, use=None) -> dict:
    """Dilution of precision for pseudoranges with a receiver-clock column.

    `az_rad`, `el_rad`: `(..., nsat)`; `use`: optional boolean `(..., nsat)` selecting the
    satellites that count (e.g. the visibility mask), so every epoch of a `(nt, nsat)`
    array is handled in one call even when the visible set changes. The geometry matrix
    has rows `[-u_e, -u_n, -u_u, 1]` (u: receiver-to-satellite unit vector in ENU), unit
    weights, and `Q = (G^T G)^-1` in ENU + clock:

    gdop = sqrt(tr Q), pdop = sqrt(Qee+Qnn+Quu), hdop = sqrt(Qee+Qnn), vdop = sqrt(Quu),
    tdop = sqrt(Qtt) (all dimensionless; multiply by the range-error sigma in m).

    Returns a dict with those five arrays of shape `(...)`, `n_used` (satellites used per
    epoch) and `reason`: an empty string when every value is finite, otherwise what made
    values NaN (fewer than 4 satellites, or a singular geometry such as every satellite at
    the same elevation, which makes the up column parallel to the clock column) with the
    number of epochs affected.
    """
    az = np.asarray(az_rad, dtype=float)
    el = np.asarray(el_rad, dtype=float)
    az, el = np.broadcast_arrays(az, el)
    if use is None:
        use = np.isfinite(az) & np.isfinite(el)
    else:
        use = np.broadcast_to(np.asarray(use, dtype=bool), az.shape) & np.isfinite(az) & np.isfinite(el)
    los = line_of_sight_enu(np.where(use, az, 0.0), np.where(use, el, 0.0))
    g = np.concatenate([-los, np.ones(los.shape[:-1] + (1,))], axis=-1)  # (..., nsat, 4)
    g = g * use[..., None]  # unused rows contribute nothing to G^T G
    normal = np.einsum("...si,...sj->...ij", g, g)  # (..., 4, 4)
    n_used = use.sum(axis=-1)

    too_few = n_used < 4
    # A unit matrix stands in where the geometry is unusable, so the batched inverse never
    # fails; those epochs are set to NaN afterwards.
    cond = np.full(n_used.shape, np.inf)
    ok = ~too_few
    if np.any(ok):
        cond[ok] = np.linalg.cond(normal[ok])
    singular = ok & ~(cond < 1e12)
    bad = too_few | singular
    normal = np.where(bad[..., None, None], np.eye(4), normal)
    q = np.linalg.inv(normal)
    diag = np.diagonal(q, axis1=-2, axis2=-1)
    out = {
        "gdop": np.sqrt(diag.sum(-1)),
        "pdop": np.sqrt(diag[..., 0] + diag[..., 1] + diag[..., 2]),
        "hdop": np.sqrt(diag[..., 0] + diag[..., 1]),
        "vdop": np.sqrt(diag[..., 2]),
        "tdop": np.sqrt(diag[..., 3]),
    }
    for key in DOP_KEYS:
        out[key] = np.where(bad, np.nan, out[key])
    reasons = []
    if np.any(too_few):
        reasons.append(f"fewer than 4 satellites at {int(np.sum(too_few))} of {too_few.size} epochs")
    if np.any(singular):
        reasons.append(f"singular geometry at {int(np.sum(singular))} of {singular.size} epochs")
    out["n_used"] = n_used
    out["reason"] = "; ".join(reasons)
    return out


def masks_for(constellations: Mapping[str, object], overrides_rad: Mapping[str, float] | None = None) -> dict[str, float]:
    """Elevation mask (rad) per constellation name: overrides first, else the paper's defaults."""
    overrides_rad = dict(overrides_rad or {})
    return {name: float(overrides_rad.get(name, default_mask_rad(name))) for name in constellations}


@dataclass(frozen=True)
class Site:
    """Receiver site: WGS84 geodetic latitude/longitude (rad), ellipsoidal height (m)."""

    lat_rad: float
    lon_rad: float
    h_m: float

    @classmethod
    def from_degrees(cls, lat_deg: float, lon_deg: float, h_m: float) -> "Site":
        """Site from degrees; a latitude/longitude out of range is a UserInputError naming it."""
        for name, value, limit in (("--lat", lat_deg, 90.0), ("--lon", lon_deg, 360.0)):
            if not math.isfinite(value) or abs(value) > limit:
                raise UserInputError(f"{name}: expected degrees within +/-{limit:g}, got {value}")
        return cls(math.radians(lat_deg), math.radians(lon_deg), float(h_m))

    @property
    def r_ecef_m(self) -> np.ndarray:
        """Site position in ECEF (m)."""
        return geodetic_to_ecef(self.lat_rad, self.lon_rad, self.h_m)

    def as_dict(self) -> dict:
        return {"lat_deg": math.degrees(self.lat_rad), "lon_deg": math.degrees(self.lon_rad), "h_m": self.h_m}
