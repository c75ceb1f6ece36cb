"""Physical constants (SI): WGS84 ellipsoid, Earth rate, normal gravity, speed of light.

Values are the published WGS84 defining and derived constants (NIMA TR8350.2) and the
IS-GPS-200 speed of light. Plain floats: no casadi import.
"""
from __future__ import annotations

C_LIGHT_MPS = 299_792_458.0          # speed of light in vacuum, m/s
WGS84_A_M = 6_378_137.0              # semi-major axis, m
WGS84_F = 1.0 / 298.257223563        # flattening
WGS84_B_M = WGS84_A_M * (1.0 - WGS84_F)  # semi-minor axis, m
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)     # first eccentricity squared
WGS84_EP2 = WGS84_E2 / (1.0 - WGS84_E2)  # second eccentricity squared
OMEGA_IE_RADPS = 7.292115e-5         # Earth rotation rate (WGS84), rad/s
WGS84_GM_M3PS2 = 3.986004418e14      # Earth gravitational constant, m^3/s^2

# Somigliana normal gravity on the ellipsoid and its height correction (TR8350.2, 4-1, 4-3)
GAMMA_E_MPS2 = 9.7803253359          # normal gravity at the equator, m/s^2
GAMMA_P_MPS2 = 9.8321849378          # normal gravity at the poles, m/s^2
SOMIGLIANA_K = (WGS84_B_M * GAMMA_P_MPS2) / (WGS84_A_M * GAMMA_E_MPS2) - 1.0
GRAVITY_M = OMEGA_IE_RADPS**2 * WGS84_A_M**2 * WGS84_B_M / WGS84_GM_M3PS2
