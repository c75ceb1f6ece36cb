"""Satellite orbits: element sets (TLE/3LE/OMM), vectorized SGP4 in ECEF, constellations, fetch.

Public API::

    from leonav_runtime.orbits import (ElementSet, RejectedEntry, load_elements,
        parse_elements_text, propagate_ecef, SatStates, starlink_walker_tle,
        gps_walker_tle, default_elements, fetch_group)

Units SI (m, m/s, m/s^2, s); frames in names (TEME from SGP4, ECEF = ITRF); times are
seconds since a UTC scenario epoch. Element sets use SGP4's WGS-72 constants, opsmode 'i'.
"""
from leonav_runtime.orbits.constellations import default_elements, gps_walker_tle, starlink_walker_tle
from leonav_runtime.orbits.elements import (
    ElementSet,
    RejectedElementsWarning,
    RejectedEntry,
    group_by_constellation,
    load_element_files,
    load_elements,
    parse_elements_text,
)
from leonav_runtime.orbits.fetch import FetchError, fetch_group
from leonav_runtime.orbits.propagate import (
    SatStates,
    StaleElementsWarning,
    acceleration_ecef_mps2,
    gravity_ecef_mps2,
    propagate_ecef,
    propagate_teme,
)

__all__ = [
    "ElementSet", "RejectedEntry", "RejectedElementsWarning", "load_elements", "load_element_files", "group_by_constellation", "parse_elements_text",
    "SatStates", "StaleElementsWarning", "propagate_ecef", "propagate_teme", "gravity_ecef_mps2",
    "acceleration_ecef_mps2", "default_elements", "gps_walker_tle", "starlink_walker_tle",
    "FetchError", "fetch_group",
]
