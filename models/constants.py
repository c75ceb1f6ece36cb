"""The one home of leonav's named constants: each with its unit and a docstring.

Physical constants are the published WGS84 defining and derived constants (NIMA
TR8350.2), the IS-GPS-200 speed of light, and the WGS-72 set that SGP4 is built on.
Project conventions (default masks, gates, the beacon carrier) live here too, so no
number is written twice. Plain floats: no casadi import.

`codegen` emits every entry of `CONSTANTS` to `leonav_runtime/gen/constants.py` (and
`constants.h`), which is how the runtime and the device code read them: they never
import `models/`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Constant:
    """A named constant: value (SI unless the unit says otherwise), unit, meaning and source."""

    name: str
    value: float
    unit: str
    doc: str


CONSTANTS: list[Constant] = []


def _const(name: str, value: float, unit: str, doc: str) -> float:
    CONSTANTS.append(Constant(name, float(value), unit, doc))
    return float(value)


# --- physics -------------------------------------------------------------------------
C_LIGHT_MPS = _const("C_LIGHT_MPS", 299_792_458.0, "m/s", "speed of light in vacuum (IS-GPS-200)")
G0_MPS2 = _const("G0_MPS2", 9.80665, "m/s^2", "standard gravity (converts g and ug datasheet figures)")

# --- WGS84 (NIMA TR8350.2) -------------------------------------------------------------
WGS84_A_M = _const("WGS84_A_M", 6_378_137.0, "m", "WGS84 semi-major axis")
WGS84_F = _const("WGS84_F", 1.0 / 298.257223563, "-", "WGS84 flattening")
WGS84_B_M = _const("WGS84_B_M", WGS84_A_M * (1.0 - WGS84_F), "m", "WGS84 semi-minor axis")
WGS84_E2 = _const("WGS84_E2", WGS84_F * (2.0 - WGS84_F), "-", "WGS84 first eccentricity squared")
WGS84_EP2 = _const("WGS84_EP2", WGS84_E2 / (1.0 - WGS84_E2), "-", "WGS84 second eccentricity squared")
OMEGA_IE_RADPS = _const("OMEGA_IE_RADPS", 7.292115e-5, "rad/s", "WGS84 Earth rotation rate")
WGS84_GM_M3PS2 = _const("WGS84_GM_M3PS2", 3.986004418e14, "m^3/s^2", "WGS84 Earth gravitational constant")
# Somigliana normal gravity on the ellipsoid and its height correction (TR8350.2, 4-1, 4-3)
GAMMA_E_MPS2 = _const("GAMMA_E_MPS2", 9.7803253359, "m/s^2", "normal gravity at the equator")
GAMMA_P_MPS2 = _const("GAMMA_P_MPS2", 9.8321849378, "m/s^2", "normal gravity at the poles")
SOMIGLIANA_K = _const("SOMIGLIANA_K", (WGS84_B_M * GAMMA_P_MPS2) / (WGS84_A_M * GAMMA_E_MPS2) - 1.0, "-",
                      "Somigliana constant k = b gamma_p / (a gamma_e) - 1")
GRAVITY_M = _const("GRAVITY_M", OMEGA_IE_RADPS**2 * WGS84_A_M**2 * WGS84_B_M / WGS84_GM_M3PS2, "-",
                   "normal-gravity height-correction ratio m = w^2 a^2 b / GM")

# --- WGS-72: the gravity model of SGP4 and of the element sets fitted for it -------------
WGS72_MU_M3PS2 = _const("WGS72_MU_M3PS2", 398600.8e9, "m^3/s^2", "WGS-72 Earth gravitational constant (SGP4)")
WGS72_RE_M = _const("WGS72_RE_M", 6_378_135.0, "m", "WGS-72 equatorial radius (SGP4)")
WGS72_J2 = _const("WGS72_J2", 0.001082616, "-", "WGS-72 zonal harmonic J2 (SGP4)")
WGS72_J3 = _const("WGS72_J3", -0.00000253881, "-", "WGS-72 zonal harmonic J3 (SGP4)")
WGS72_J4 = _const("WGS72_J4", -0.00000165597, "-", "WGS-72 zonal harmonic J4 (SGP4)")
OMEGA_EARTH_TEME_RADPS = _const("OMEGA_EARTH_TEME_RADPS", 7.292115146706979e-5, "rad/s",
                                "Earth rotation rate of Vallado's teme2ecef (LOD = 0)")

# --- Starlink beacons --------------------------------------------------------------------
STARLINK_BEACON_HZ = _const("STARLINK_BEACON_HZ", 11.325e9, "Hz",
                            "Starlink Ku-band beacon carrier used in the paper (central tone of the channel)")
KU_DOWNLINK_MIN_HZ = _const("KU_DOWNLINK_MIN_HZ", 10.7e9, "Hz",
                            "lower edge of the Ku downlink; a capture RF centre below it is not a beacon carrier")
KU_DOWNLINK_MAX_HZ = _const("KU_DOWNLINK_MAX_HZ", 12.75e9, "Hz",
                            "upper edge of the Ku downlink; a capture RF centre above it is not a beacon carrier")
COMB_SPACING_HZ = _const("COMB_SPACING_HZ", 43949.5, "Hz", "spacing of the beacon tones around a channel centre")

# --- project conventions -------------------------------------------------------------------
STARLINK_MASK_DEG = _const("STARLINK_MASK_DEG", 28.0, "deg",
                           "Starlink elevation mask (paper Sec. II: what Starlink user terminals use)")
GNSS_MASK_DEG = _const("GNSS_MASK_DEG", 10.0, "deg", "GNSS elevation mask (paper Sec. II, common GNSS practice)")
CHI2_1DOF_999 = _const("CHI2_1DOF_999", 10.827566170662733, "-",
                       "chi-square quantile, 1 dof, p = 0.999: the default NIS gate of a scalar update")
DEG_RAD = _const("DEG_RAD", math.pi / 180.0, "rad/deg", "one degree in radians")
