"""GNSS measurements and broadcast ephemerides (docs/gnss.md).

    from leonav_runtime.gnss import (read_rinex_nav, read_rinex_navs, read_rinex_obs,
        Ephemerides, ObservationTable, states_for_observations)
    from leonav_runtime.gnss.ubx_log import read_ubx_log   # u-blox logs (uses hardware/)

Epochs are continuous GPS seconds (`leonav_runtime.gnss.time`); satellite equations are
in `leonav_runtime.orbits.broadcast`.
"""
from leonav_runtime.gnss.ephemeris import EPH_DTYPE, Ephemerides, Rejection
from leonav_runtime.gnss.observations import ObservationTable, rawx_to_table
from leonav_runtime.gnss.rinex_nav import NavFile, parse_rinex_nav, read_rinex_nav, read_rinex_navs
from leonav_runtime.gnss.rinex_obs import parse_rinex_obs, read_rinex_obs
from leonav_runtime.gnss.sat_states import ObservedSatStates, states_for_observations

__all__ = ["EPH_DTYPE", "Ephemerides", "Rejection", "ObservationTable", "rawx_to_table", "NavFile",
           "parse_rinex_nav", "read_rinex_nav", "read_rinex_navs", "parse_rinex_obs", "read_rinex_obs",
           "ObservedSatStates", "states_for_observations"]
