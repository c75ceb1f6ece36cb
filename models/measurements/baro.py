"""Barometric altimeter: the receiver's WGS84 ellipsoidal height (m) plus a slowly walking bias.

    z = h_ell(r_U) + b_baro

h_ell is the geodetic height of the IMU's ECEF position (Bowring's closed form,
models.frames.geodetic_from_ecef), so the barometer sees the height above the ellipsoid, not
the ENU up coordinate (they part by d^2 / 2R: 8 m at 10 km from the origin). The pressure
height of a barometer set to the reference pressure at the start (QNH) carries an offset of a
few metres and drifts with the weather (about 1 hPa, 8 m, in three hours): that is the bias
state b_baro, a random walk. The lever arm between IMU and barometer is not modelled (it is
below a barometer's noise for vehicle-sized arms).

Scenario section `[baro]` (rate_hz, sigma_m) and dataset section `[baro]` come from the
registry entries below; modes add the word `baro` after imu: `gps+imu+baro`, `leo-alpha+imu+baro`.
"""
from __future__ import annotations

from leonav.models import frames
from leonav.models import registry as R
from leonav.models.measurements.geometry import receiver_ecef
from leonav.models.state import X

PARAMS = (
    R.Param("baro_bias_rw", "m/sqrt(s)", "barometer bias random walk (weather: ~8 m in 3 h)", default=0.05,
            example=0.05),
)
STATES = (
    R.StateBlock("b_baro", 1, "m", "barometric height bias", R.RandomWalk(density="baro_bias_rw"),
                 R.Prior(5.0, doc="a barometer set to the reference pressure at the start (QNH): a few metres"),
                 fd_step=1e-2, typical=5.0, error_doc="barometric height bias error"),
)


def h(x, aux, p):
    """Barometric height (m): ellipsoidal height of the IMU plus the bias."""
    r_U, _ = receiver_ecef(x, p)
    return frames.geodetic_from_ecef(r_U)[2] + x[X["b_baro"].offset]


OBSERVABLES = (
    R.Observable("BARO_HEIGHT", "baro_height", 17, h, "m", source="local", token="baro", stream="baro",
                 table="local", rate_hz=10.0,
                 noise=R.Noise("baro.sigma_m", 0.5, 1e-3, 1e3, "1-sigma barometric height noise (MEMS sensor, 10 Hz)"),
                 doc="barometric altimeter: ellipsoidal height plus a random-walk bias"),
)
