"""Replay modes and options.

Modes name what the filter fuses with the IMU: `fix+imu` (GNSS position fixes),
`leo-alpha+imu` (Starlink Doppler-rate, the paper's name), `fix+leo-alpha+imu` (both), and
the tightly coupled `pseudorange+imu` (the receiver's RXM-RAWX code pseudoranges and Doppler
range rates) and `pseudorange+leo-alpha+imu` (those and the Doppler-rate). The default runs
the first three; the pseudorange modes are asked for with `--modes`, and so are the carrier-phase
modes `leo-phase+imu` and `leo-phase+alpha+imu` (the tones' tracked phase, time-differenced:
docs/carrier.md).
`gps+imu` means GPS *pseudoranges* everywhere else (scenarios, sweeps), so the replay's
position-fix modes say `fix`; the old names `gps+imu` and `gps+leo-alpha+imu` are
accepted as aliases with a note.
"""
from __future__ import annotations

import dataclasses
import math

from leonav_runtime.core import filter as lfilter
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gen.constants import GNSS_MASK_DEG
from leonav_runtime.core import model

MODES = ("fix+imu", "leo-alpha+imu", "fix+leo-alpha+imu")
"""The modes a replay runs by default."""
ALL_MODES = MODES + ("pseudorange+imu", "pseudorange+leo-alpha+imu", "leo-phase+imu", "leo-phase+alpha+imu")
"""The replay's modes as listed in help and completion; any mode of `replayable` words is accepted."""


def replayable(o) -> bool:
    """What a recorded session gives the filter: GNSS fixes, the raw GNSS observations of
    RXM-RAWX (tightly coupled modes), the beacon capture's Doppler-rates and its tones'
    tracked carrier phase (time-differenced)."""
    return o.stream in ("fix", "doppler_rate", "carrier_phase") or o.table == "gnss_obs"


def uses_carrier_phase(modes) -> bool:
    """Whether any of the modes fuses the tracked carrier phase (the `phase` word)."""
    return any("carrier_phase" in replay_mode(m).streams for m in modes)


def replay_mode(name: str, where: str = "--modes:") -> model.Mode:
    """A replay mode (its observables and record streams), or a UserInputError naming `where`."""
    return model.parse_mode(name, replayable, where)


def uses_raw_gnss(mode: str) -> bool:
    """Whether the mode fuses a receiver's raw pseudoranges (tightly coupled)."""
    return any(o.table == "gnss_obs" for o in replay_mode(mode).observables)
LATENCY_PRIOR_SIGMA_S = 0.3
"""Prior sigma (s) of the fix latency when it is estimated (`gnss_latency_s = "estimate"`)."""
LATENCY_RANDOM_WALK = 1e-4
"""Random walk (s/sqrt(s)) of an estimated fix latency."""


def latency_given_s(latency: float | str) -> float:
    """The latency the time map removes: the given one, 0 when the filter estimates it."""
    return 0.0 if latency == "estimate" else float(latency)


def latency_values(latency: float | str) -> dict[str, float]:
    """Registry parameters for the fix latency: the state moves only when it is estimated."""
    return {"dt_fix_rw": LATENCY_RANDOM_WALK if latency == "estimate" else 0.0}


def latency_estimate(x, p_diag, layout) -> dict[str, float]:
    """The fix latency state of a state x (NX,) and its error variances p_diag (NDX,): value and
    1-sigma (s), as every run reports it (`fix_latency_s`)."""
    return {"value": float(x[layout.X_DT_FIX]), "sigma": float(math.sqrt(p_diag[layout.DX_DDT_FIX]))}


def parse_latency(text: str, option: str = "--gnss-latency") -> float | str:
    """A command-line latency: seconds in [0, 1) or the word 'estimate'."""
    if text == "estimate":
        return text
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and 0 <= value < 1):
        raise UserInputError(f"{option}: {text!r}: expected seconds in [0, 1) or 'estimate'")
    return value


MODE_ALIASES = {"gps+imu": "fix+imu", "gps+leo-alpha+imu": "fix+leo-alpha+imu"}
"""Old replay mode names (they meant position fixes) -> the current ones."""
DOPPLER_RATE_SIGMA_FLOOR_HZ_S = 0.5   # the fit sigma can be optimistic for short ridges


@dataclasses.dataclass
class ReplayOptions:
    modes: tuple[str, ...] = MODES
    origin_deg: tuple[float, float, float] | None = None   # lat deg, lon deg, ellipsoidal height m
    yaw_deg: float | None = None                           # initial heading, from East towards North
    doppler_rate_sigma_floor_hz_s: float = DOPPLER_RATE_SIGMA_FLOOR_HZ_S
    gate_nis: float = lfilter.CHI2_1DOF_999
    use_truth: bool = True
    gnss_latency_s: float | str = 0.0   # receiver output latency (epoch -> first byte), if measured (PPS);
                                         # "estimate": the filter's fix latency state (LATENCY_PRIOR_SIGMA_S)
    nav_paths: tuple[str, ...] = ()  # RINEX navigation files for the pseudorange modes (besides RXM-SFRBX)
    elevation_mask_deg: float = GNSS_MASK_DEG   # pseudorange modes: satellites below are not used
    reference_file: dict | None = None   # --reference: path and how to read it (commands/run.reference_options)
    operator_ephemerides: str | None = None   # --operator-ephemerides: folder of operator files (docs/ephemerides.md)
    corrections: str | None = None            # --corrections: a base's recorded line stream (docs/corrections.md)
    corrections_max_age_s: float | None = None  # None: inputs.corrections.DEFAULT_MAX_AGE_S
    orbit_states_sigma_m: tuple[float, float, float] | None = None   # --orbit-states: offsets as states, prior m


def canonical_modes(modes) -> tuple[tuple[str, ...], list[str]]:
    """Modes with the old names replaced, and one note per replaced name."""
    out, notes = [], []
    for m in modes:
        if m in MODE_ALIASES:
            notes.append(f"mode {m!r} is now {MODE_ALIASES[m]!r} (position fixes; 'gps+imu' means GPS "
                         "pseudoranges in scenarios)")
            m = MODE_ALIASES[m]
        if m not in out:
            out.append(m)
    return tuple(out), notes


def check_options(options: ReplayOptions) -> ReplayOptions:
    """The options with canonical mode names, or a UserInputError naming the bad one."""
    modes, _ = canonical_modes(options.modes)
    for m in modes:
        replay_mode(m)
    if not 0.0 <= options.elevation_mask_deg <= 90.0:
        raise UserInputError(f"--elevation-mask: {options.elevation_mask_deg!r}: expected degrees in 0..90")
    sig = options.orbit_states_sigma_m
    if sig is not None and not (len(sig) == 3 and all(math.isfinite(v) and v > 0 for v in sig)):
        raise UserInputError(f"--orbit-states: {sig}: expected three sigmas > 0 m (radial, along, cross), "
                             "e.g. 240,960,170 for element sets 6 h old")
    if sig is not None and options.corrections:
        raise UserInputError("--orbit-states with --corrections: a base's corrections remove the orbit error the "
                             "states would estimate; use one")
    if options.origin_deg is not None and not all(math.isfinite(v) for v in options.origin_deg):
        raise UserInputError(f"--origin: {options.origin_deg}: expected finite LAT LON H")
    return dataclasses.replace(options, modes=modes)
