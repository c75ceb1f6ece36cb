"""Reference attitude columns -> the yaw leonav scores: the heading of the body x axis (forward,
the same axis in FRD and FLU) from East towards North, rad.

`[reference] attitude` says what the columns hold:
- `quat_enu`: a quaternion body -> local level East-North-Up; `quat_ned`: body -> local level
  North-East-Down. For an EPSG (projected) reference, "local level" is the CRS grid's: the
  meridian convergence `conv_rad` turns grid yaw into true yaw.
- `quat_ecef`: body -> ECEF; the body x axis is turned into the local ENU at each reference
  position (lat, lon), so no convergence applies.
- `euler_deg`: roll, pitch, yaw (deg) of the Z-Y-X sequence, yaw from North clockwise (the
  NED convention; grid North for an EPSG reference): the yaw of body x is 90 deg - yaw.
Quaternions are Hamilton, scalar `w`, rotating body vectors into the frame
(v_frame = q v_body q*), in `quaternion_order` ("xyzw" or "wxyz"). One whose norm is not 1
within NORM_TOL (zero, a column of something else, a mis-scaled export) is flagged bad.
"""
from __future__ import annotations

import numpy as np

NORM_TOL = 1e-3


def quaternion_xyzw(q: np.ndarray, order: str) -> np.ndarray:
    """(n, 4) quaternion columns in `order` -> (n, 4) x y z w."""
    return q[:, [1, 2, 3, 0]] if order == "wxyz" else q


def body_x(q_xyzw: np.ndarray) -> np.ndarray:
    """(n, 3): the body x axis in the quaternion's target frame (first column of its rotation matrix)."""
    x, y, z, w = q_xyzw.T
    return np.column_stack([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)])


def reference_yaw(cols: np.ndarray, attitude: str, order: str, lat_rad: np.ndarray, lon_rad: np.ndarray,
                  conv_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(yaw rad from East towards North (n,), bad (n,) bool) of attitude columns `cols` (module doc);
    lat_rad, lon_rad: the reference positions (for quat_ecef); conv_rad: grid convergence."""
    if attitude == "euler_deg":
        return np.pi / 2 - np.radians(cols[:, 2]) + conv_rad, np.zeros(cols.shape[0], bool)
    q = quaternion_xyzw(np.asarray(cols, float), order)
    norm = np.linalg.norm(q, axis=1)
    bad = ~(np.abs(norm - 1.0) <= NORM_TOL)
    q = q / np.where(bad, 1.0, norm)[:, None]
    c = body_x(q)
    if attitude == "quat_ned":        # (N, E, D)
        return np.arctan2(c[:, 0], c[:, 1]) + conv_rad, bad
    if attitude == "quat_ecef":       # ECEF -> local ENU at each position
        sl, cl, sp, cp = np.sin(lon_rad), np.cos(lon_rad), np.sin(lat_rad), np.cos(lat_rad)
        east = -sl * c[:, 0] + cl * c[:, 1]
        north = -sp * cl * c[:, 0] - sp * sl * c[:, 1] + cp * c[:, 2]
        return np.arctan2(north, east), bad
    return np.arctan2(c[:, 1], c[:, 0]) + conv_rad, bad
