"""The one definition of the state, error state, parameters, aux input and observables.

Pure Python (no casadi). The layout is the mechanization's own blocks (`CORE_STATES`: the 9D
navigation state and the IMU biases) followed by the blocks every measurement module declares
(`models.registry`); the parameters are `CORE_PARAMS` followed by the modules' own; the
observables are the modules' `OBSERVABLES` in kind-id order. `codegen` emits all of it as
`leonav_runtime/gen/state_layout.h`, its Python twin `state_layout.py` and the runtime's
registry `gen/registry.py`. Layouts follow docs/design.md.

The dicts `X`, `DX`, `P`, `AUX`, `U` are filled in place: a models module imported while the
measurement modules are discovered may hold them at its top, but reads block offsets and the
sizes (`NX`, `NDX`, ...) only when its functions run.
"""
from __future__ import annotations

from dataclasses import dataclass

from leonav.models import registry as R


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


_NAV_TRUTH = R.Truth(start="zero", stream="none")   # the simulator's truth motion is the mechanization's

CORE_STATES = (
    R.StateBlock("p_enu", 3, "m", "position in the local ENU frame at the origin r0", R.Mechanization(),
                 R.Prior(given=True, doc="initial position sigma of the run"), role="navigation", fd_step=1e-2,
                 typical=300.0, truth=_NAV_TRUTH, error="dp", error_doc="position error, ENU"),
    R.StateBlock("v_enu", 3, "m/s", "velocity w.r.t. Earth, ENU axes", R.Mechanization(),
                 R.Prior(given=True, doc="initial velocity sigma of the run"), role="navigation", fd_step=1e-3,
                 typical=30.0, truth=_NAV_TRUTH, error="dv", error_doc="velocity error, ENU"),
    R.StateBlock("q_nb", 4, "-", "attitude quaternion body->ENU [w x y z]", R.Mechanization(),
                 R.Prior(given=True, doc="initial attitude sigma of the run"), role="navigation", fd_step=1e-4,
                 typical=1.0, truth=_NAV_TRUTH, error_size=3, error="dtheta", error_unit="rad",
                 error_doc="attitude error, body frame: q_true = q_nom (x) exp(dtheta/2)"),
    R.StateBlock("b_a", 3, "m/s^2", "accelerometer bias, body", R.RandomWalk(density="acc_bias_rw"),
                 R.Prior(profile_field="acc_bias_sigma", doc="the IMU profile's bias stability"), role="imu",
                 fd_step=1e-3, typical=1e-2, truth=R.Truth("prior", "trial"), error_doc="accelerometer bias error"),
    R.StateBlock("b_g", 3, "rad/s", "gyro bias, body",
                 R.GaussMarkov(beta="gyro_bias_beta", density="gyro_bias_rw"),
                 R.Prior(profile_field="gyro_bias_sigma", doc="the IMU profile's bias stability"), role="imu",
                 fd_step=1e-4, typical=1e-3, truth=R.Truth("prior", "trial"), error_doc="gyro bias error"),
)
"""The mechanization's blocks: the 9D navigation state (dp, dv, dtheta lead dx) and the IMU biases."""

CORE_PARAMS = (
    R.Param("lat0_rad", "rad", "ENU origin geodetic latitude (WGS84)", example=0.75),
    R.Param("lon0_rad", "rad", "ENU origin longitude", example=-1.35),
    R.Param("h0_m", "m", "ENU origin ellipsoidal height", example=170.0),
    R.Param("vrw", "m/s/sqrt(s)", "velocity random walk (accelerometer white noise); IMU profile", example=1e-3),
    R.Param("arw", "rad/sqrt(s)", "angle random walk (gyro white noise); IMU profile", example=1e-4),
    R.Param("acc_bias_rw", "m/s^2/sqrt(s)", "accelerometer bias random walk; IMU profile", example=1e-5),
    R.Param("gyro_bias_rw", "rad/s/sqrt(s)", "gyro bias driving-noise density (random walk, or the Gauss-Markov "
            "process's); IMU profile", example=1e-7),
    R.Param("q_cdt", "m^2/s", "clock white-frequency PSD (drives c_dt); clock profile", example=0.01),
    R.Param("q_cddt", "m^2/s^3", "clock random-walk-frequency PSD (drives c_ddt); clock profile", example=0.03),
    R.Param("q_blo", "Hz^2/s", "LO offset random-walk PSD", example=0.01),
    R.Param("f_c_hz", "Hz", "beacon carrier frequency", example=11.325e9),
    # GNSS antenna position relative to the IMU, body FLU (a calibration, not a state: 0 = co-located)
    R.Param("lever_x_m", "m", "GNSS antenna lever arm, body forward (from the IMU to the antenna phase centre)",
            default=0.0, example=0.54),
    R.Param("lever_y_m", "m", "GNSS antenna lever arm, body left", default=0.0, example=-0.22),
    R.Param("lever_z_m", "m", "GNSS antenna lever arm, body up", default=0.0, example=1.16),
    R.Param("gyro_bias_beta", "1/s", "gyro bias Gauss-Markov rate 1/tau (0: random walk); IMU profile",
            default=0.0, example=1.0 / 600.0),
)

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
    # GNSS velocity: the antenna's rotation about the IMU (lever arm); zeros for every other observable
    ("w_b", 3, "rad/s", "latest angular rate, body (the gyro averaged like f_b)"),
    # GNSS fix and velocity: the measurement's tag is this long after the state's time (the latest
    # IMU sample); zero for every other observable
    ("dt_tag", 1, "s", "time from the state (latest IMU sample) to the measurement's tag, >= 0"),
    # carrier phase: the span of its time difference; zeros for every other observable
    ("dt_phase", 1, "s", "interval of a time-differenced carrier phase, (t - dt_phase, t]"),
    ("r_S_prev_ecef", 3, "m", "satellite position at t - dt_phase, ECEF (the same ephemeris as r_S_ecef)"),
    ("df_tone", 1, "Hz", "carrier phase: the tone's offset from the channel centre its phase is referred to "
     "(the sample clock scales it: s_clk T df_tone)"),
])
# IMU input u
U_BLOCKS = _blocks([
    ("dtheta_b", 3, "rad", "gyro angle increment over dt, body FLU"),
    ("dvel_b", 3, "m/s", "accelerometer velocity increment over dt, body FLU"),
])
# Record kinds that are not observables (measurement records carry their observable's index):
# an IMU interval (strapdown predict) and a constant-velocity predict (no IMU).
KIND_IMU = -1
KIND_CV = -2
# The 9D navigation error (dp, dv, dtheta): the leading blocks of dx that are scored and
# bounded (NEES, the PCRB's B_nav).
NAV_BLOCKS = ("dp", "dv", "dtheta")
NOISE_SECTIONS = {"gps", "starlink"}
"""Scenario sections that hold the sigma keys of simulated satellite observables."""


def _fill(target: dict, blocks: tuple[Block, ...]) -> None:
    target.clear()
    target.update({b.name: b for b in blocks})


def _layout(states: tuple[R.StateBlock, ...]) -> tuple[tuple[Block, ...], tuple[Block, ...]]:
    x = _blocks([(s.name, s.size, s.unit, s.doc) for s in states])
    dx = _blocks([(s.error_name, s.nerr, s.err_unit, s.error_doc or f"{s.doc} error") for s in states])
    return x, dx


def _param_blocks(params: tuple[R.Param, ...]) -> tuple[Block, ...]:
    return _blocks([(p.name, 1, p.unit, p.doc) for p in params])


# the mechanization's blocks first: modules imported during discovery may read these offsets
X: dict[str, Block] = {}
DX: dict[str, Block] = {}
P: dict[str, Block] = {}
AUX = {b.name: b for b in AUX_BLOCKS}
U = {b.name: b for b in U_BLOCKS}
_fill(X, _layout(CORE_STATES)[0])
_fill(DX, _layout(CORE_STATES)[1])
_fill(P, _param_blocks(CORE_PARAMS))

DECLARATIONS = R.module_declarations()
STATES: tuple[R.StateBlock, ...] = CORE_STATES + tuple(s for d in DECLARATIONS for s in d.states)
"""Every state block, in layout order, with its registry entry (dynamics, prior, truth, ...)."""
PARAMS: tuple[R.Param, ...] = CORE_PARAMS + tuple(p for d in DECLARATIONS for p in d.params)
MEASUREMENTS: tuple[R.Observable, ...] = tuple(sorted((o for d in DECLARATIONS for o in d.observables),
                                                      key=lambda o: o.kind_id))
"""Every observable (`registry.Observable`: name, suffix, dim, unit, h, source, ...) in kind-id order."""
R.check(STATES, PARAMS, MEASUREMENTS, NOISE_SECTIONS)

X_BLOCKS, DX_BLOCKS = _layout(STATES)
P_BLOCKS = _param_blocks(PARAMS)
_fill(X, X_BLOCKS)
_fill(DX, DX_BLOCKS)
_fill(P, P_BLOCKS)
STATE = {s.name: s for s in STATES}
"""Registry entry of each state block by its nominal name."""
ERROR_STATE = {s.error_name: s for s in STATES}
"""Registry entry of each state block by its error-state name."""


def _total(blocks: tuple[Block, ...]) -> int:
    return blocks[-1].offset + blocks[-1].size


NX = _total(X_BLOCKS)
NDX = _total(DX_BLOCKS)
NP = _total(P_BLOCKS)
NAUX = _total(AUX_BLOCKS)
NU = _total(U_BLOCKS)
NMEAS = len(MEASUREMENTS)
NNAV = sum(DX[name].size for name in NAV_BLOCKS)

assert [DX[name].offset for name in NAV_BLOCKS] == [0, 3, 6], "the 9D block must lead dx"
