"""The one definition of the state, error state, parameters, aux input and observables.

Pure Python (no casadi): `codegen` emits these as `leonav_runtime/gen/state_layout.h`
and its Python twin `state_layout.py`. Layouts follow docs/design.md.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Block:
    """A named slice of a vector: `offset`, `size`, unit and meaning."""

    name: str
    offset: int
    size: int
    unit: str
    doc: str

    @property
    def slice(self) -> slice:
        return slice(self.offset, self.offset + self.size)


def _blocks(spec: list[tuple[str, int, str, str]]) -> tuple[Block, ...]:
    out, offset = [], 0
    for name, size, unit, doc in spec:
        out.append(Block(name, offset, size, unit, doc))
        offset += size
    return tuple(out)


# Nominal state x
X_BLOCKS = _blocks([
    ("p_enu", 3, "m", "position in the local ENU frame at the origin r0"),
    ("v_enu", 3, "m/s", "velocity w.r.t. Earth, ENU axes"),
    ("q_nb", 4, "-", "attitude quaternion body->ENU [w x y z]"),
    ("b_a", 3, "m/s^2", "accelerometer bias, body"),
    ("b_g", 3, "rad/s", "gyro bias, body"),
    ("c_dt", 1, "m", "receiver clock bias times c"),
    ("c_ddt", 1, "m/s", "receiver clock drift times c"),
    ("b_lo", 1, "Hz", "beacon front-end frequency offset at baseband"),
    ("isb", 2, "m", "inter-system biases [Galileo - GPS, BeiDou - GPS] of the receiver clock, times c"),
])
# Error state dx (attitude as a body-frame rotation vector)
DX_BLOCKS = _blocks([
    ("dp", 3, "m", "position error, ENU"),
    ("dv", 3, "m/s", "velocity error, ENU"),
    ("dtheta", 3, "rad", "attitude error, body frame: q_true = q_nom (x) exp(dtheta/2)"),
    ("db_a", 3, "m/s^2", "accelerometer bias error"),
    ("db_g", 3, "rad/s", "gyro bias error"),
    ("dc_dt", 1, "m", "clock bias error"),
    ("dc_ddt", 1, "m/s", "clock drift error"),
    ("db_lo", 1, "Hz", "LO offset error"),
    ("disb", 2, "m", "inter-system bias errors [Galileo - GPS, BeiDou - GPS]"),
])
# Parameters p
P_NAMES = (
    ("lat0_rad", "rad", "ENU origin geodetic latitude (WGS84)"),
    ("lon0_rad", "rad", "ENU origin longitude"),
    ("h0_m", "m", "ENU origin ellipsoidal height"),
    ("vrw", "m/s/sqrt(s)", "velocity random walk (accelerometer white noise)"),
    ("arw", "rad/sqrt(s)", "angle random walk (gyro white noise)"),
    ("acc_bias_rw", "m/s^2/sqrt(s)", "accelerometer bias random walk"),
    ("gyro_bias_rw", "rad/s/sqrt(s)", "gyro bias random walk"),
    ("q_cdt", "m^2/s", "clock white-frequency PSD (drives c_dt)"),
    ("q_cddt", "m^2/s^3", "clock random-walk-frequency PSD (drives c_ddt)"),
    ("q_blo", "Hz^2/s", "LO offset random-walk PSD"),
    ("f_c_hz", "Hz", "beacon carrier frequency"),
    # GNSS antenna position relative to the IMU, body FLU (a calibration, not a state: 0 = co-located)
    ("lever_x_m", "m", "GNSS antenna lever arm, body forward (from the IMU to the antenna phase centre)"),
    ("lever_y_m", "m", "GNSS antenna lever arm, body left"),
    ("lever_z_m", "m", "GNSS antenna lever arm, body up"),
)
P_BLOCKS = _blocks([(n, 1, u, d) for n, u, d in P_NAMES])
# Auxiliary measurement input
AUX_BLOCKS = _blocks([
    ("r_S_ecef", 3, "m", "satellite position, ECEF (pseudorange: at transmit time, ECEF of transmit epoch)"),
    ("v_S_ecef", 3, "m/s", "satellite velocity, ECEF (Earth-relative)"),
    ("a_S_ecef", 3, "m/s^2", "satellite acceleration, ECEF (Earth-relative)"),
    ("r_ref_ecef", 3, "m", "reference satellite position, ECEF (OFDM differenced range)"),
    ("v_ref_ecef", 3, "m/s", "reference satellite velocity, ECEF"),
    ("a_ref_ecef", 3, "m/s^2", "reference satellite acceleration, ECEF"),
    ("f_b", 3, "m/s^2", "latest specific force, body (receiver acceleration)"),
    # GNSS observables (GNSS_PSEUDORANGE, GNSS_RANGE_RATE); zeros for every other observable
    ("sat_clock", 2, "m, m/s", "satellite clock offset c dt_sv (relativistic term and the signal's group "
     "delay included) and drift c d(dt_sv)/dt"),
    ("t_sod", 1, "s", "GPS time of day of reception (Klobuchar local time)"),
    ("iono_scale", 1, "-", "(f_L1 / f)^2 of the signal: scales the Klobuchar L1 delay; 0 = no ionosphere term"),
    ("tropo_scale", 1, "-", "1 = Saastamoinen troposphere applied, 0 = not"),
    ("isb_select", 2, "-", "[1 if Galileo, 1 if BeiDou]: which inter-system bias the signal carries"),
    ("klobuchar", 8, "s, s/sc, s/sc^2, s/sc^3, s, s/sc, s/sc^2, s/sc^3",
     "GPS broadcast ionosphere alpha0..3, beta0..3 (IS-GPS-200 20.3.3.5.1.7)"),
])
# IMU input u
U_BLOCKS = _blocks([
    ("dtheta_b", 3, "rad", "gyro angle increment over dt, body FLU"),
    ("dvel_b", 3, "m/s", "accelerometer velocity increment over dt, body FLU"),
])


@dataclass(frozen=True)
class Observable:
    """One observable. Its kind id (`LEONAV_MEAS_<name>`) is its index in MEASUREMENTS;
    `suffix` names its generated functions (`leonav_h_<suffix>`, `leonav_update_<suffix>`,
    `leonav_pcrb_info_<suffix>`); `dim` is the size of z
    (1: the filter's updates are scalar and sequential); `unit` is the unit of z."""

    name: str
    suffix: str
    dim: int
    unit: str


# Observables, in kind-id order. Adding one here (and its h in models/measurements/) is all
# the generated code and the C driver need: codegen emits the table (LEONAV_MEAS_TABLE).
MEASUREMENTS = (
    Observable("PSEUDORANGE", "pseudorange", 1, "m"),
    Observable("POS_E", "pos_e", 1, "m"),
    Observable("POS_N", "pos_n", 1, "m"),
    Observable("POS_U", "pos_u", 1, "m"),
    Observable("VEL_E", "vel_e", 1, "m/s"),
    Observable("VEL_N", "vel_n", 1, "m/s"),
    Observable("VEL_U", "vel_u", 1, "m/s"),
    Observable("DOPPLER_RATE", "doppler_rate", 1, "Hz/s"),
    Observable("DOPPLER", "doppler", 1, "Hz"),
    Observable("OFDM_RANGE_DIFF", "ofdm_range_diff", 1, "m"),
    Observable("GNSS_PSEUDORANGE", "gnss_pseudorange", 1, "m"),
    Observable("GNSS_RANGE_RATE", "gnss_range_rate", 1, "m/s"),
    # motion constraints of a ground vehicle: z = 0 with their own R (docs/design.md "Motion constraints")
    Observable("NHC_Y", "nhc_y", 1, "m/s"),
    Observable("NHC_Z", "nhc_z", 1, "m/s"),
    Observable("ZUPT_E", "zupt_e", 1, "m/s"),
    Observable("ZUPT_N", "zupt_n", 1, "m/s"),
    Observable("ZUPT_U", "zupt_u", 1, "m/s"),
)
# Record kinds that are not observables (measurement records carry their observable's index):
# an IMU interval (strapdown predict) and a constant-velocity predict (no IMU).
KIND_IMU = -1
KIND_CV = -2


def _total(blocks: tuple[Block, ...]) -> int:
    return blocks[-1].offset + blocks[-1].size


NX = _total(X_BLOCKS)
NDX = _total(DX_BLOCKS)
NP = _total(P_BLOCKS)
NAUX = _total(AUX_BLOCKS)
NU = _total(U_BLOCKS)
NMEAS = len(MEASUREMENTS)
# The 9D navigation error (dp, dv, dtheta): the leading blocks of dx that are scored and
# bounded (NEES, the PCRB's B_nav).
NAV_BLOCKS = ("dp", "dv", "dtheta")

X = {b.name: b for b in X_BLOCKS}
DX = {b.name: b for b in DX_BLOCKS}
P = {b.name: b for b in P_BLOCKS}
AUX = {b.name: b for b in AUX_BLOCKS}
U = {b.name: b for b in U_BLOCKS}
NNAV = sum(DX[name].size for name in NAV_BLOCKS)

assert (NX, NDX, NP, NAUX, NU, NNAV) == (21, 20, 14, 36, 6, 9), "layout drifted from docs/design.md"
assert [DX[name].offset for name in NAV_BLOCKS] == [0, 3, 6], "the 9D block must lead dx"
