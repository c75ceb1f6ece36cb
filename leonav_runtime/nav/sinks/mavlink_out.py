"""MAVLink output of a navigation solution (pymavlink): GPS_INPUT and GLOBAL_POSITION_SENSOR.

GPS_INPUT is what PX4 and ArduPilot accept from a companion computer as a GPS: position
(degE7, altitude MSL in m — leonav writes the ellipsoidal height, as in its GGA), NED
velocity, horizontal/vertical/speed accuracy (m, m/s) and heading, stamped in GPS time
(week, ms of week). GLOBAL_POSITION_SENSOR reports the same fix as a navigation source:
with the LEO source value where the installed MAVLink dialect defines one
(`GLOBAL_POSITION_SRC_LEO`), otherwise as an estimator (`GLOBAL_POSITION_SRC_ESTIMATOR`),
which `source_name` reports. The default link is UDP to 127.0.0.1:14550.
"""
from __future__ import annotations

import math

from leonav_runtime.gnss.time import utc_to_gps_seconds
from leonav_runtime.nav.sinks.solution import NavSolution

WEEK_S = 604800.0


class MavlinkOutput:
    """Send GPS_INPUT (+ GLOBAL_POSITION_SENSOR) for each solution over a pymavlink link."""

    def __init__(self, url: str = "udpout:127.0.0.1:14550", system_id: int = 1, component_id: int = 220,
                 gps_id: int = 0) -> None:
        import os

        os.environ.setdefault("MAVLINK20", "1")  # GLOBAL_POSITION_SENSOR (id > 255) needs MAVLink 2
        from pymavlink import mavutil
        from pymavlink.dialects.v20 import common

        self._common = common
        self.link = mavutil.mavlink_connection(url, source_system=system_id, source_component=component_id,
                                               dialect="common")
        self.gps_id = gps_id
        leo = getattr(common, "GLOBAL_POSITION_SRC_LEO", None)
        self.source = leo if leo is not None else common.GLOBAL_POSITION_SRC_ESTIMATOR
        self.source_name = "GLOBAL_POSITION_SRC_LEO" if leo is not None else "GLOBAL_POSITION_SRC_ESTIMATOR"
        self.counts = {"gps_input": 0, "global_position_sensor": 0}

    def send(self, sol: NavSolution) -> None:
        mav = self.link.mav
        t_gps = utc_to_gps_seconds(sol.utc)
        week = int(t_gps // WEEK_S)
        week_ms = int(round((t_gps - week * WEEK_S) * 1000.0))
        lat_e7, lon_e7 = int(round(sol.lat_deg * 1e7)), int(round(sol.lon_deg * 1e7))
        ve, vn, vu = sol.v_enu_mps
        sig_e, sig_n, sig_u = sol.sigma_enu_m
        speed_acc = math.hypot(*sol.sigma_v_enu_mps[:2]) if all(map(math.isfinite, sol.sigma_v_enu_mps[:2])) else 0.0
        fix_type = 3 if sol.fix_quality > 0 else 0
        hdop = sol.sigma_horizontal_m / 1.5
        yaw_cdeg = int(round(sol.heading_deg * 100.0)) or 36000  # 0 means "no yaw" in GPS_INPUT
        time_usec = int(round(sol.utc.timestamp() * 1e6))
        mav.gps_input_send(time_usec, self.gps_id, 0, week_ms, week, fix_type, lat_e7, lon_e7, float(sol.h_m),
                           float(hdop), float(sig_u / 1.5), float(vn), float(ve), float(-vu), float(speed_acc),
                           float(sol.sigma_horizontal_m), float(sig_u), int(min(sol.n_gnss + sol.n_leo, 255)),
                           yaw_cdeg)
        self.counts["gps_input"] += 1
        mav.global_position_sensor_send(0, 0, self.gps_id, time_usec, 0, self.source, 0, lat_e7, lon_e7,
                                        float(sol.h_m), float(sol.h_m), float(sol.sigma_horizontal_m), float(sig_u))
        self.counts["global_position_sensor"] += 1

    def close(self) -> None:
        self.link.close()
