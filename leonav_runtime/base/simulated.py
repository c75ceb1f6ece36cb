"""A simulated base/rover pair that shares one ephemeris error draw.

`write_pair(folder, ...)` writes two synthetic sessions (`simulation.session_synth`) whose beacon
tones are synthesized from the *true* orbits, element sets perturbed once per satellite, while
both receivers' pipelines predict from the element sets as published (the built-in Walker set at
the capture's UTC minute, which is what `leonav nav`, `leonav replay` and `leonav base` use when
no --tle is given):

    folder/rover/      the rover's session (its site, its seed)
    folder/base/       the base's session at the base's known position (another seed: its own
                       noise and LO), the same true orbits
    folder/pair.json   the base's known position, the error draw (seed, sigmas) and the
                       per-satellite offsets actually applied

The ephemeris error is the realism model's (`simulation.realism.starlink_sigma_rac`, the
`[ephemeris_error]` defaults: 960 m along-track at 6 h), applied to the element sets as an
along-track offset: a shift of the mean anomaly by d_A / a (a time shift along the orbit, as
`realism.perturb_states` applies it). Radial and cross-track (240 and 170 m at 6 h) are not
applied here: changing them in mean elements changes the orbit's period and plane, not only its
position; the along-track term is 92 % of the variance at 6 h.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from leonav_runtime.common.output import write_json
from leonav_runtime.orbits import geometry

EARTH_MU_M3_S2 = 3.986004418e14   # WGS84 GM (m^3/s^2), for the semi-major axis of a mean motion


def along_track_errors_m(norad_ids: np.ndarray, seed: int, sigma_along_m: float) -> np.ndarray:
    """(n,) along-track orbit errors (m), one per satellite, drawn from the stream (seed, NORAD id):
    the same satellite gets the same error in the rover's and the base's world."""
    return np.array([np.random.default_rng([int(seed), int(i)]).standard_normal() * sigma_along_m
                     for i in np.asarray(norad_ids).tolist()])


def true_elements(elements, d_along_m: np.ndarray):
    """A copy of the ElementSet with each satellite's mean anomaly advanced by d_along / a (rad)."""
    from sgp4.api import WGS72, Satrec

    sats = []
    for s, d in zip(elements.satrecs, np.asarray(d_along_m, float)):
        n_radps = s.no_kozai / 60.0
        a_m = (EARTH_MU_M3_S2 / n_radps ** 2) ** (1.0 / 3.0)
        t = Satrec()
        t.sgp4init(WGS72, "i", s.satnum, s.jdsatepoch + s.jdsatepochF - 2433281.5, s.bstar, s.ndot, s.nddot,
                   s.ecco, s.argpo, s.inclo, (s.mo + d / a_m) % (2 * math.pi), s.no_kozai, s.nodeo)
        sats.append(t)
    return dataclasses.replace(elements, satrecs=sats)


def offset_position(lat_deg: float, lon_deg: float, h_m: float, east_m: float, north_m: float,
                    up_m: float = 0.0) -> tuple[float, float, float]:
    """(lat deg, lon deg, h m) of the point east/north/up (m) of the given one."""
    lat0, lon0 = math.radians(lat_deg), math.radians(lon_deg)
    r0 = geometry.geodetic_to_ecef(lat0, lon0, h_m)
    lat, lon, h = geometry.ecef_to_geodetic(geometry.enu_to_ecef(np.array([[east_m, north_m, up_m]]), r0, lat0, lon0))
    return math.degrees(float(np.ravel(lat)[0])), math.degrees(float(np.ravel(lon)[0])), float(np.ravel(h)[0])


def write_pair(folder: str | Path, seconds: float = 12.0, base_offset_en_m: tuple[float, float] = (12_000.0, 16_000.0),
               error_seed: int = 22, element_age_days: float = 0.25, rover_seed: int = 0, base_seed: int = 1,
               sdr_rate_hz: float = 240e3, ephemeris_error: bool = True) -> dict:
    """Write the pair (module doc); returns pair.json's content. base_offset_en_m: the base east,
    north of the rover's site (m; default 20 km); element_age_days: the age whose realism sigma is
    drawn from; ephemeris_error False: true orbits = element sets (a control)."""
    from leonav_runtime.scenarios.schema import SCHEMA
    from leonav_runtime.simulation.realism import starlink_sigma_rac
    from leonav_runtime.simulation.session_synth import SynthSessionConfig, builtin_starlink, write_synthetic_session

    folder = Path(folder)
    rover_cfg = SynthSessionConfig(seconds=seconds, seed=rover_seed, sdr_rate_hz=sdr_rate_hz)
    base_pos = offset_position(rover_cfg.lat_deg, rover_cfg.lon_deg, rover_cfg.alt_m, *base_offset_en_m)
    base_pos = (base_pos[0], base_pos[1], rover_cfg.alt_m)     # on the same height (the Earth curves away)
    base_cfg = dataclasses.replace(rover_cfg, seed=base_seed, lat_deg=base_pos[0], lon_deg=base_pos[1],
                                   alt_m=base_pos[2], lo_offset_hz=17e3)
    nominal = builtin_starlink(rover_cfg.epoch_utc)
    eph = {k: f.default for k, f in SCHEMA["ephemeris_error"].items()} | {"element_age_days": element_age_days}
    sigma = starlink_sigma_rac(eph)
    d_along = (along_track_errors_m(nominal.norad_ids, error_seed, float(sigma[1])) if ephemeris_error
               else np.zeros(len(nominal)))
    truth = true_elements(nominal, d_along)
    rover = write_synthetic_session(folder / "rover", rover_cfg, elements=truth, overwrite=True)
    index = {int(i): k for k, i in enumerate(nominal.norad_ids.tolist())}
    heard = [index[i] for i in _norad_ids(rover.sdr_info) if i in index]
    # the base hears the rover's satellites (20 km apart, they see the same sky; the synthesizer
    # would otherwise pick its own with its own seed)
    base = write_synthetic_session(folder / "base", base_cfg, elements=truth.select(heard), overwrite=True)
    used = sorted({int(s) for info in (rover.sdr_info, base.sdr_info) for s in _norad_ids(info)})
    doc = {"note": "simulated base/rover pair (leonav_runtime.base.simulated): both sessions' tones come from the "
                   "same true orbits; their receivers predict from the published element sets",
           "base_position_deg_m": list(base_pos), "rover_site_deg_m": [rover_cfg.lat_deg, rover_cfg.lon_deg,
                                                                     rover_cfg.alt_m],
           "base_offset_en_m": list(base_offset_en_m), "baseline_m": float(math.hypot(*base_offset_en_m)),
           "ephemeris_error": bool(ephemeris_error), "error_seed": error_seed, "element_age_days": element_age_days,
           "sigma_rac_m": sigma.tolist(), "applied": "along-track only (mean anomaly)",
           "along_track_error_m": {str(i): float(d_along[index[i]]) for i in used if i in index},
           "epoch_utc": rover_cfg.epoch_utc, "seconds": seconds}
    write_json(folder / "pair.json", doc)
    return doc


def _norad_ids(sdr_info: dict) -> list[int]:
    """NORAD ids of the satellites a synthetic capture holds (its truth names them)."""
    return [int(i) for i in sdr_info.get("norad_ids", [])]
