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

# --- GNSS broadcast ephemeris: the constants each signal-in-space ICD fixes --------------
# Satellite orbit and clock from a broadcast ephemeris must use the constants of its own
# ICD (the control segment fits the elements with them), not WGS84's.
GPS_MU_M3PS2 = _const("GPS_MU_M3PS2", 3.986005e14, "m^3/s^2",
                      "Earth gravitational constant for GPS/QZSS broadcast orbits (IS-GPS-200, 20.3.3.4.3)")
GPS_OMEGA_E_RADPS = _const("GPS_OMEGA_E_RADPS", 7.2921151467e-5, "rad/s",
                           "Earth rotation rate for GPS/QZSS broadcast orbits (IS-GPS-200, 20.3.3.4.3)")
GPS_F_REL_S_PER_SQRTM = _const("GPS_F_REL_S_PER_SQRTM", -4.442807633e-10, "s/m^0.5",
                               "relativistic clock constant F = -2 sqrt(mu)/c^2 (IS-GPS-200, 20.3.3.3.3.1)")
GPS_PI = _const("GPS_PI", 3.1415926535898, "-",
                "the value of pi the GPS ICD fixes for semicircle <-> radian conversion (IS-GPS-200, 20.3.3.4.3)")
GAL_MU_M3PS2 = _const("GAL_MU_M3PS2", 3.986004418e14, "m^3/s^2",
                      "Earth gravitational constant for Galileo broadcast orbits (Galileo OS SIS ICD, 5.1.1)")
GAL_OMEGA_E_RADPS = _const("GAL_OMEGA_E_RADPS", 7.2921151467e-5, "rad/s",
                           "Earth rotation rate for Galileo broadcast orbits (Galileo OS SIS ICD, 5.1.1)")
GAL_F_REL_S_PER_SQRTM = _const("GAL_F_REL_S_PER_SQRTM", -4.442807309e-10, "s/m^0.5",
                               "relativistic clock constant F for Galileo (Galileo OS SIS ICD, 5.1.4)")
BDS_MU_M3PS2 = _const("BDS_MU_M3PS2", 3.986004418e14, "m^3/s^2",
                      "Earth gravitational constant for BeiDou broadcast orbits, CGCS2000 (BDS-SIS-ICD-B1I, 5.2.4)")
BDS_OMEGA_E_RADPS = _const("BDS_OMEGA_E_RADPS", 7.2921150e-5, "rad/s",
                           "Earth rotation rate for BeiDou broadcast orbits, CGCS2000 (BDS-SIS-ICD-B1I, 5.2.4)")
BDS_F_REL_S_PER_SQRTM = _const("BDS_F_REL_S_PER_SQRTM", -4.442807309e-10, "s/m^0.5",
                               "relativistic clock constant F for BeiDou (BDS-SIS-ICD-B1I, 5.2.4.10)")
BDS_GEO_TILT_RAD = _const("BDS_GEO_TILT_RAD", -5.0 * math.pi / 180.0, "rad",
                          "BeiDou GEO orbit frame: rotation about x of the user frame, -5 deg (BDS-SIS-ICD-B1I, 5.2.4.12)")
GPS_WEEK_S = _const("GPS_WEEK_S", 604800.0, "s", "one GPS (and Galileo, BeiDou) week")
BDT_MINUS_GPST_S = _const("BDT_MINUS_GPST_S", -14.0, "s",
                          "BeiDou time minus GPS time (BDT epoch 2006-01-01 00:00:00 UTC, BDS-SIS-ICD-B1I 4.2)")
BDT_WEEK_OFFSET = _const("BDT_WEEK_OFFSET", 1356.0, "week", "GPS week number of BDT week 0")
GPS_L1_HZ = _const("GPS_L1_HZ", 1575.42e6, "Hz", "GPS/QZSS L1, Galileo E1, BeiDou B1C carrier (IS-GPS-200, 3.3.1.1)")
GPS_L2_HZ = _const("GPS_L2_HZ", 1227.60e6, "Hz", "GPS/QZSS L2 carrier (IS-GPS-200, 3.3.1.1)")
GPS_L5_HZ = _const("GPS_L5_HZ", 1176.45e6, "Hz", "GPS/QZSS L5, Galileo E5a, BeiDou B2a carrier (IS-GPS-705)")
GAL_E5B_HZ = _const("GAL_E5B_HZ", 1207.14e6, "Hz", "Galileo E5b, BeiDou B2I/B2b carrier (Galileo OS SIS ICD, 2.3)")
GAL_E6_HZ = _const("GAL_E6_HZ", 1278.75e6, "Hz", "Galileo E6 carrier")
BDS_B1I_HZ = _const("BDS_B1I_HZ", 1561.098e6, "Hz", "BeiDou B1I carrier (BDS-SIS-ICD-B1I, 3.2)")
BDS_B3I_HZ = _const("BDS_B3I_HZ", 1268.52e6, "Hz", "BeiDou B3I carrier")
GLO_G1_HZ = _const("GLO_G1_HZ", 1602.0e6, "Hz", "GLONASS G1 FDMA centre (slot k: + k * GLO_G1_STEP_HZ)")
GLO_G1_STEP_HZ = _const("GLO_G1_STEP_HZ", 0.5625e6, "Hz", "GLONASS G1 FDMA channel spacing")
GLO_G2_HZ = _const("GLO_G2_HZ", 1246.0e6, "Hz", "GLONASS G2 FDMA centre (slot k: + k * GLO_G2_STEP_HZ)")
GLO_G2_STEP_HZ = _const("GLO_G2_STEP_HZ", 0.4375e6, "Hz", "GLONASS G2 FDMA channel spacing")
GPS_FIT_INTERVAL_DEFAULT_S = _const("GPS_FIT_INTERVAL_DEFAULT_S", 4.0 * 3600.0, "s",
                                    "GPS curve-fit interval when the fit flag is 0 or unknown (IS-GPS-200, 20.3.3.4.3.1)")
GAL_EPH_VALIDITY_S = _const("GAL_EPH_VALIDITY_S", 4.0 * 3600.0, "s",
                            "span over which a Galileo ephemeris is used (nominal validity; OS SIS ICD 5.1.1 lists 4 h)")
BDS_EPH_VALIDITY_S = _const("BDS_EPH_VALIDITY_S", 2.0 * 3600.0, "s",
                            "span over which a BeiDou ephemeris is used (hourly uploads; +-1 h around toe)")

# --- GNSS signal propagation: the models of models/measurements/gnss_atmosphere.py ----------
# Standard atmosphere that drives the Saastamoinen model when no meteorological data are
# given (the usual choice of single-point software; RTKLIB's tropmodel uses the same).
STD_PRESSURE_HPA = _const("STD_PRESSURE_HPA", 1013.25, "hPa", "standard-atmosphere pressure at height 0")
STD_TEMPERATURE_K = _const("STD_TEMPERATURE_K", 288.15, "K", "standard-atmosphere temperature at height 0 (15 C)")
STD_LAPSE_RATE_KPM = _const("STD_LAPSE_RATE_KPM", 6.5e-3, "K/m", "standard-atmosphere temperature lapse rate")
STD_REL_HUMIDITY = _const("STD_REL_HUMIDITY", 0.7, "-", "relative humidity assumed for the wet delay")
TROPO_MIN_HEIGHT_M = _const("TROPO_MIN_HEIGHT_M", -100.0, "m",
                            "below this ellipsoidal height the troposphere term is 0 (outside the model)")
TROPO_MAX_HEIGHT_M = _const("TROPO_MAX_HEIGHT_M", 1.0e4, "m",
                            "above this ellipsoidal height the troposphere term is 0 (standard atmosphere "
                            "below the tropopause only)")

ISB_RW_PSD_M2PS = _const("ISB_RW_PSD_M2PS", 1e-6, "m^2/s",
                         "random-walk PSD of the receiver inter-system biases (hardware delays drifting with "
                         "temperature: 6 cm in an hour); a constant until the parameter vector carries one")

# --- GNSS pseudorange error model (single point and GNSS records): RTKLIB's defaults -------
# var = PR_ERR_A^2 + PR_ERR_B^2 / sin(el) + URA^2 + PR_ERR_CODE_BIAS^2 + var_iono + var_tropo,
# var_iono = PR_ERR_IONO_OFF^2 without a correction, (PR_ERR_BRDC_IONO_FACTOR * I)^2 with
# Klobuchar; var_tropo = PR_ERR_TROPO_OFF^2 without, (PR_ERR_SAAS / (sin el + 0.1))^2 with.
PR_ERR_A_M = _const("PR_ERR_A_M", 0.3, "m", "code noise, elevation-independent part")
PR_ERR_B_M = _const("PR_ERR_B_M", 0.3, "m", "code noise, part that grows as 1/sqrt(sin el)")
PR_ERR_CODE_BIAS_M = _const("PR_ERR_CODE_BIAS_M", 0.3, "m", "code bias error (uncorrected inter-signal bias)")
PR_ERR_IONO_OFF_M = _const("PR_ERR_IONO_OFF_M", 5.0, "m", "1-sigma of the ionosphere when it is not corrected")
PR_ERR_TROPO_OFF_M = _const("PR_ERR_TROPO_OFF_M", 3.0, "m", "1-sigma of the troposphere when it is not corrected")
PR_ERR_BRDC_IONO_FACTOR = _const("PR_ERR_BRDC_IONO_FACTOR", 0.5, "-",
                                 "1-sigma of the Klobuchar residual as a fraction of the correction")
PR_ERR_SAAS_M = _const("PR_ERR_SAAS_M", 0.3, "m", "1-sigma of the Saastamoinen residual at zenith (/(sin el + 0.1))")
RANGE_RATE_SIGMA_MPS = _const("RANGE_RATE_SIGMA_MPS", 0.1, "m/s",
                              "default 1-sigma of a Doppler-derived range rate (about 0.5 Hz at L1)")
SPP_CHI2_ALPHA = _const("SPP_CHI2_ALPHA", 1e-3, "-",
                        "false-alarm probability of the single-point chi-square residual test (RTKLIB's table)")
SPP_MAX_GDOP = _const("SPP_MAX_GDOP", 30.0, "-", "single-point solutions with a larger GDOP are rejected")

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
