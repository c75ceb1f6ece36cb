"""Satellite orbits: element sets (TLE/3LE/OMM), vectorized SGP4 in ECEF, constellations, fetch.

Public API::

    from leonav_runtime.orbits import (ElementSet, RejectedEntry, load_elements,
        parse_elements_text, propagate_ecef, SatStates, starlink_walker_tle,
        gps_walker_tle, default_elements, fetch_group)

Units SI (m, m/s, m/s^2, s); frames in names (TEME from SGP4, ECEF = ITRF); times are
seconds since a UTC scenario epoch. Element sets use SGP4's WGS-72 constants, opsmode 'i'.
"""
from leonav_runtime.common.lazy_exports import lazy_exports

# names per module, imported on first use (lazy_exports.py): broadcast-ephemeris users
# (`leonav spp`) do not import SGP4, the element readers or the HTTP client
__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "constellations": ("default_elements", "gps_walker_tle", "group_by_constellation", "starlink_walker_tle"),
    "elements": ("ElementSet", "RejectedElementsWarning", "RejectedEntry",
                 "load_element_files", "load_elements", "parse_elements_text"),
    "fetch": ("FetchError", "fetch_group"),
    "propagate": ("SatStates", "StaleElementsWarning", "acceleration_ecef_mps2", "gravity_ecef_mps2",
                  "propagate_ecef", "propagate_teme"),
})
