"""The scenario schema: every key of a scenario file with its type, unit, range and default.

`load.py` validates files against `SCHEMA` and converts them to SI; docs/scenarios.md
carries the table `load.schema_markdown()` generates from it. The sigma keys of the simulated
satellite observables and a section per local sensor (`[baro]`: its rate, sigma and the
parameters it declares) come from the model registry (`core.model`), not from this file.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import functools
import math

from leonav_runtime.core import model
from leonav_runtime.core.params import IMU_PROFILES as IMU_PROFILE_DATA
from leonav_runtime.gen.constants import CHI2_1DOF_999, STARLINK_BEACON_HZ, STARLINK_MASK_DEG

MODES = model.PAPER_MODES
"""The default fusion modes of a scenario: the paper's (registry). Any mode of the simulated
observables can be asked for by name (`mode_of`): `gps+imu+baro`, `leo-doppler+imu`, ..."""


@functools.lru_cache(maxsize=None)
def mode_of(name: str, where: str = "[monte_carlo] modes") -> model.Mode:
    """A scenario mode: its observables among the simulated ones (satellites, local sensors)."""
    return model.parse_mode(name, model.simulated, where)

IMU_PROFILES = tuple(IMU_PROFILE_DATA)  # names of the emitted profiles (gen/profiles.py): tactical, wt901
TRAJECTORY_KINDS, SELECTION_RULES = ("static", "maneuvers"), ("highest-elevation", "random")


@dataclass(frozen=True)
class Field:
    """One scenario key: its type, unit (conversion to SI), bounds and default."""

    kind: type | tuple[type, ...]
    unit: str  # "deg" converts to rad; others are already SI
    lo: float | None = None
    hi: float | None = None
    default: Any = ...
    choices: tuple[str, ...] | None = None
    doc: str = ""


_REQUIRED = ...

# section -> key -> Field. The unit suffix in the key name is the unit in the file.
SCHEMA: dict[str, dict[str, Field]] = {
    "": {
        "name": Field(str, "-", default="scenario", doc="short name used in output folders"),
        "description": Field(str, "-", default="", doc="one line shown in metrics.json"),
    },
    "site": {
        "lat_deg": Field(float, "deg", -90, 90, default=43.0848638, doc="WGS84 geodetic latitude"),
        "lon_deg": Field(float, "deg", -180, 360, default=-77.6786127, doc="WGS84 longitude"),
        "alt_m": Field(float, "m", -500, 1e5, default=170.0, doc="WGS84 ellipsoidal height"),
    },
    "time": {
        "epoch": Field(str, "UTC", default=_REQUIRED, doc="scenario start, ISO 8601 UTC"),
        "duration_s": Field(float, "s", 1e-3, 86400, default=_REQUIRED, doc="length of the run"),
    },
    "trajectory": {
        "kind": Field(str, "-", default="static", choices=TRAJECTORY_KINDS,
                      doc="static receiver, or a vessel driven by `maneuvers`"),
        "attitude_deg": Field(list, "deg", default=[0.0, 0.0, 90.0],
                              doc="initial roll, pitch, yaw; yaw from East towards North"),
        "speed_mps": Field(float, "m/s", 0, 400, default=0.0, doc="initial speed along heading"),
        # Each manoeuvre: [duration_s, acceleration_mps2, turn_rate_deg_s]
        "maneuvers": Field(list, "mixed", default=[],
                           doc="[[duration_s, acceleration_mps2, turn_rate_deg_s], ...] in order"),
        "roll_amplitude_deg": Field(float, "deg", 0, 45, default=0.0, doc="wave-induced roll"),
        "pitch_amplitude_deg": Field(float, "deg", 0, 45, default=0.0, doc="wave-induced pitch"),
        "wave_period_s": Field(float, "s", 0.5, 60, default=8.0, doc="period of the roll/pitch motion"),
    },
    "imu": {
        "profile": Field(str, "-", default="tactical", choices=IMU_PROFILES,
                         doc="noise figures: models/imu.py (sources cited there)"),
        "rate_hz": Field(float, "Hz", 1, 2000, default=100.0, doc="IMU sample rate"),
    },
    "gps": {
        "rate_hz": Field(float, "Hz", 0.01, 100, default=10.0, doc="pseudorange epoch rate"),
        "elevation_mask_deg": Field(float, "deg", -5, 90, default=10.0, doc="GPS mask (paper: 10 deg)"),
        "max_satellites": Field(int, "-", 4, 64, default=8, doc="highest GPS satellites used per epoch"),
        "clock_bias_m": Field(float, "m", -1e6, 1e6, default=100.0, doc="true initial c*dt"),
        "clock_drift_mps": Field(float, "m/s", -1e3, 1e3, default=0.1, doc="true initial c*ddt"),
        "outages_s": Field(list, "s", default=[], doc="[[start_s, end_s], ...] GPS denied"),
    },
    "starlink": {
        "rate_hz": Field(float, "Hz", 0.01, 100, default=1.0, doc="Starlink measurement epoch rate"),
        "carrier_hz": Field(float, "Hz", 1e9, 3e10, default=STARLINK_BEACON_HZ, doc="beacon channel centre"),
        "elevation_mask_deg": Field(float, "deg", -5, 90, default=STARLINK_MASK_DEG, doc="Starlink mask (paper: 28 deg)"),
        "counts": Field(list, "-", default=[5, 10, 15, 20, 25, 30, 35, 40, 45],
                        doc="Starlink satellite counts swept"),
        "selection": Field(str, "-", default="highest-elevation", choices=SELECTION_RULES,
                           doc="which N satellites are used (see the rules in scenario.py)"),
        "selection_seed": Field(int, "-", 0, 2**63 - 1, default=0,
                                doc="seed of the `random` rule's satellite priorities"),
        "lo_offset_hz": Field(float, "Hz", -5e6, 5e6, default=120e3, doc="true LNB LO offset"),
        "sample_clock_error": Field(float, "-", -1e-3, 1e-3, default=0.5e-6,
                                    doc="true SDR sample-clock fractional frequency error (0.5e-6: an RTL-SDR V3 TCXO)"),
    },
    "elements": {
        "source": Field(str, "-", default="builtin", choices=("builtin", "files"),
                        doc="generated Walker constellations at the epoch, or `files`"),
        "files": Field(list, "-", default=[], doc="TLE/OMM paths, relative to the scenario file"),
    },
    "filter": {
        "initial_position_sigma_m": Field(float, "m", 1e-3, 1e6, default=10.0, doc="prior per ENU axis"),
        "initial_velocity_sigma_mps": Field(float, "m/s", 1e-4, 1e3, default=0.5, doc="prior per ENU axis"),
        "initial_attitude_sigma_deg": Field(float, "deg", 1e-4, 180, default=1.0, doc="prior per axis"),
        "gate_nis": Field(float, "-", 0, 1e6, default=CHI2_1DOF_999, doc="chi2(1) 99.9 %; 0 disables"),
        "covariance_interval_s": Field(float, "s", 0, 1, default=0.0,
                                       doc="0: P propagated at every IMU sample; > 0: once per interval this "
                                       "long (and before every update), the nominal still at every sample"),
    },
    # Realism switches: the truth differs from what the filter assumes (off by default).
    # `enabled` switches the truth; the compensation keys switch the filter, on or off alone.
    "ephemeris_error": {
        "enabled": Field(bool, "-", default=False, doc="true satellite orbits differ from the elements"),
        # Starlink: Jankovic (2026, arXiv:2605.19850), SGP4 vs next TLE, pooled median 3D error ~1 km
        # at 6 h, shaped like the GPS split below; GPS: TLE vs broadcast RMS, docs/gnss.md.
        "starlink_sigma_rac_m": Field(list, "m", default=[240.0, 960.0, 170.0],
                                      doc="Starlink radial, along, cross 1-sigma at `reference_age_days`"),
        "gps_sigma_rac_m": Field(list, "m", default=[1180.0, 4770.0, 860.0],
                                 doc="GPS radial, along, cross 1-sigma (TLE vs broadcast, no growth)"),
        "apply_to": Field(list, "-", default=["starlink"], doc="constellations perturbed: starlink, gps"),
        "element_age_days": Field(float, "d", 0, 30, default=0.25, doc="age of the Starlink elements"),
        "reference_age_days": Field(float, "d", 1e-3, 30, default=0.25, doc="age the Starlink sigmas hold at"),
        "growth_exponent": Field(float, "-", 0, 3, default=1.09,
                                 doc="sigma ~ age^k (1 km at 6 h to 38 km at 7 d: k = 1.09)"),
        "compensate": Field(str, "-", default="none", choices=("none", "inflate-r", "consider", "states"),
                            doc="filter: R plus the orbit error's effect on each measurement (inflate-r: "
                                "one-sigma moves at the truth; consider: J P_sat J^T at the prior); with [base] "
                                "orbit corrections, what the served covariance does instead; states: each Starlink "
                                "satellite's radial, along, cross offset estimated as states (method 1, prior: "
                                "the Starlink sigmas at the element age; a differenced range and GPS keep the "
                                "consider term)"),
        "orbit_state_slots": Field(int, "-", 1, 256, default=64,
                                   doc="states: satellites whose offsets are states at once"),
        "orbit_state_free_after_s": Field(float, "s", 0.1, 1e5, default=30.0,
                                          doc="states: a satellite without records this long gives its slot up"),
        "orbit_state_walk_m2_s": Field(float, "m^2/s", 0, 1e6, default=0.0,
                                       doc="states: random-walk PSD of each offset (0: random constants)"),
        "consider_correlation_s": Field(float, "s", 0, 1e5, default=0.0,
                                        doc="consider: the term times the satellite's records within this "
                                            "time (its error is shared); 0 = white"),
        "operator_folder": Field(str, "-", default="",
                                 doc="consider: P_sat from the operator ephemerides in this folder (MANIFEST.txt; "
                                     "relative to the scenario file) instead of the Starlink sigmas; "
                                     "docs/ephemerides.md"),
    },
    "base": {
        "enabled": Field(bool, "-", default=False, doc="a base station's differential corrections (ephemeris method 3): "
                         "the same true orbits seen at a known position, applied to every Starlink observable"),
        "offset_enu_m": Field(list, "m", default=[20000.0, 0.0, 0.0],
                              doc="the base's position from the site, East North Up (at rest)"),
        "corrections": Field(str, "-", default="orbit", choices=("orbit", "measurement"),
                             doc="orbit: each satellite's radial/along/cross offset fitted at the base and the "
                                 "rover's satellite states moved by it; measurement: the orbit error's effect "
                                 "at the base, subtracted (decays with the baseline); simulation/base_station.py"),
        "serve_interval_s": Field(float, "s", 0.1, 60.0, default=1.0,
                                  doc="orbit corrections: the base serves a new fit this often (each from its "
                                      "measurements up to then)"),
    },
    "front_end": {
        "enabled": Field(bool, "-", default=False, doc="carrier phase: C/N0 by elevation, LO phase noise, cycle slips "
                         "(simulation/front_end.py)"),
        "cn0_dbhz": Field(list, "dB-Hz", default=[20.0, 35.0], doc="tone C/N0 at the Starlink mask and at the zenith"),
        "pll_bandwidth_hz": Field(float, "Hz", 0.1, 1000, default=10.0, doc="the tracking loop's noise bandwidth"),
        "lo_phase_noise_dbc_hz": Field(float, "dBc/Hz", -200, 0, default=-50.0,
                                       doc="LNB LO SSB phase noise at lo_phase_noise_offset_hz (white FM)"),
        "lo_phase_noise_offset_hz": Field(float, "Hz", 1, 1e7, default=1000.0, doc="offset of that figure"),
        "slip_below_dbhz": Field(float, "dB-Hz", 0, 60, default=25.0, doc="tones weaker than this can slip"),
        "slip_probability": Field(float, "-", 0, 1, default=1e-3, doc="per epoch of a weak tone"),
        "slips_detected": Field(float, "-", 0, 1, default=0.95, doc="fraction the tracker flags (epoch dropped)"),
        "compensate": Field(bool, "-", default=False,
                            doc="filter: the LO random walk q_blo that follows the LO's white FM at the epoch rate"),
    },
    "imu_errors": {
        "enabled": Field(bool, "-", default=False, doc="IMU errors the filter does not model"),
        # 1-sigma = a third of the InvenSense MPU-9250 spec tolerances (consumer MEMS)
        "accel_scale_factor_ppm": Field(float, "ppm", 0, 1e5, default=10000.0, doc="per-axis scale factor"),
        "gyro_scale_factor_ppm": Field(float, "ppm", 0, 1e5, default=10000.0, doc="per-axis scale factor"),
        "misalignment_mrad": Field(float, "mrad", 0, 100, default=6.7, doc="cross-axis terms, per element"),
        "g_sensitivity_deg_s_per_g": Field(float, "deg/s/g", 0, 10, default=0.1,
                                           doc="gyro error per specific force, per element"),
        "temperature_rate_c_per_s": Field(float, "degC/s", -1, 1, default=0.02, doc="warm-up ramp"),
        "accel_bias_tempco_mg_per_c": Field(float, "mg/degC", 0, 100, default=0.5, doc="per axis"),
        "gyro_bias_tempco_deg_s_per_c": Field(float, "deg/s/degC", 0, 10, default=0.01, doc="per axis"),
        "process_noise_inflation": Field(float, "-", 1, 1e4, default=1.0,
                                         doc="filter: VRW, ARW and bias walks times this"),
    },
    "monte_carlo": {
        "trials": Field(int, "-", 1, 100000, default=100, doc="trials per (mode, count)"),
        "seed": Field(int, "-", 0, 2**63 - 1, default=1, doc="master seed"),
        "modes": Field(list, "-", default=list(MODES), doc="the paper's: " + ", ".join(MODES) + "; or any mode named "
                       "by the simulated observables' words, e.g. gps+imu+baro (leonav_runtime/gen/REGISTRY.md)"),
        "paper_findings": Field(bool, "-", default=False, doc="check the paper's findings on this run (the paper's "
                                "own scenarios say true; elsewhere its verdicts mean nothing)"),
    },
}


def _unit_of(key: str) -> str:
    """The unit a key's suffix names (sigma_m -> m, rate_hz -> Hz, declination_deg -> deg)."""
    suffix = key.rsplit("_", 1)[-1]
    return {"m": "m", "mps": "m/s", "hz": "Hz", "deg": "deg", "s": "s", "rad": "rad", "pa": "Pa", "t": "T"}.get(
        suffix, suffix)


def _registry_fields() -> None:
    """The satellite observables' sigma keys into their constellation's section, and one section per
    local sensor: its rate, sigma and the scenario keys of its parameters (registry)."""
    for o in model.OBSERVABLES:
        if o.noise is None or not model.simulated(o):
            continue
        n = o.noise
        section = SCHEMA.setdefault(n.section, {})
        if o.table == "local" and "rate_hz" not in section:
            section["rate_hz"] = Field(float, "Hz", 0.01, 1000, default=o.rate_hz, doc=f"{o.token} sample rate")
        section[n.key] = Field(float, _unit_of(n.key), n.lo, n.hi, default=n.default, doc=n.doc)
    for q in model.PARAMS:
        if q.scenario:
            section, _, key = q.scenario.partition(".")
            unit = _unit_of(key)
            value = q.default if unit != "deg" else math.degrees(q.default)
            SCHEMA.setdefault(section, {})[key] = Field(float, unit, q.lo, q.hi, default=value, doc=q.doc)


_registry_fields()
