"""One navigation solution as the live outputs see it (geodetic, SI units)."""
from __future__ import annotations

import datetime as _dt
import json
import math
from dataclasses import asdict, dataclass, field

import numpy as np


@dataclass(frozen=True)
class NavSolution:
    """The filter's state at one time, in the units of the outputs.

    utc: time of the solution; lat_rad, lon_rad, h_m: WGS84 geodetic position (ellipsoidal
    height); v_enu_mps: velocity East/North/Up; rpy_rad: roll, pitch, yaw (yaw from East
    towards North, the project's convention); sigma_enu_m / sigma_v_enu_mps: 1-sigma of
    position and velocity per ENU axis; yaw_sigma_rad; mode: the filter mode name;
    n_gnss / n_leo: measurements used in the last second; fix_quality: 0 none, 1 GNSS
    aided, 6 dead reckoning (GNSS lost, IMU and Starlink only).
    """

    utc: _dt.datetime
    lat_rad: float
    lon_rad: float
    h_m: float
    v_enu_mps: tuple[float, float, float]
    rpy_rad: tuple[float, float, float]
    sigma_enu_m: tuple[float, float, float]
    sigma_v_enu_mps: tuple[float, float, float] = (float("nan"),) * 3
    yaw_sigma_rad: float = float("nan")
    mode: str = ""
    n_gnss: int = 0
    n_leo: int = 0
    fix_quality: int = 1
    latency_s: float = float("nan")
    extra: dict = field(default_factory=dict)

    @property
    def lat_deg(self) -> float:
        return math.degrees(self.lat_rad)

    @property
    def lon_deg(self) -> float:
        return math.degrees(self.lon_rad)

    @property
    def heading_deg(self) -> float:
        """Heading clockwise from North (deg, 0..360) from the yaw (East towards North)."""
        return (90.0 - math.degrees(self.rpy_rad[2])) % 360.0

    @property
    def sigma_horizontal_m(self) -> float:
        """1-sigma horizontal position error (m): sqrt(sigma_e^2 + sigma_n^2)."""
        return math.hypot(self.sigma_enu_m[0], self.sigma_enu_m[1])

    def json_line(self) -> str:
        """One JSON object (units in the key names), newline-terminated."""
        d = asdict(self)
        d["utc"] = self.utc.isoformat()
        d["lat_deg"], d["lon_deg"] = self.lat_deg, self.lon_deg
        del d["lat_rad"], d["lon_rad"]
        return json.dumps(_finite_or_null(d), allow_nan=False) + "\n"


def _finite_or_null(v):
    """JSON has no NaN: non-finite numbers become null (recursively)."""
    if isinstance(v, dict):
        return {k: _finite_or_null(x) for k, x in v.items()}
    if isinstance(v, (list, tuple, np.ndarray)):
        return [_finite_or_null(x) for x in v]
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(v) else None
    if isinstance(v, np.integer):
        return int(v)
    return v
