"""Built-in constellations generated as TLE text (no real element set is copied).

Walker-delta shells i: T/P/F: plane j (0..P-1) has RAAN = j 360/P, satellite k (0..S-1) of
that plane has mean anomaly k 360/S + j F 360/T. The output is ordinary 3LE text with
correct checksums, so it goes through the same `parse_elements_text` path as real sets.

Mean elements: a TLE carries SGP4's *Kozai* mean motion. We want the SGP4 mean
semi-major axis (Brouwer, the `a` SGP4 recovers after removing the J2 Kozai term) to be
R_E + altitude, so we invert SGP4's recovery (`initl`: a1 = (ke/n)^(2/3), del, ...) for the
Kozai mean motion by fixed-point iteration. The mean orbit radius then equals R_E + h
within the J2 short-period terms (~1 km). Altitude is above the equatorial radius
R_E = 6378.137 km, as the filings state it. Eccentricity 1e-4, argument of perigee 0,
B* = 0 (no drag): the elements are exact at the given epoch (age 0).

NORAD ids are in 90000-99999, unused by the real catalog (which is below 70,000 in 2026;
80000-89999 is the analyst range): GPS 90000-90030, Starlink 90100 + serial. Names say
"-W" (Walker) so they cannot be mistaken for real satellites.
"""
from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass

from leonav_runtime.orbits.elements import ElementSet, as_utc, parse_elements_text
from leonav_runtime.orbits.tle import format_tle
from leonav_runtime.gen.constants import WGS72_J2, WGS72_MU_M3PS2, WGS72_RE_M, WGS84_A_M

R_EQUATOR_KM = WGS84_A_M / 1e3
# SGP4 WGS-72 constants (what `Satrec.twoline2rv(..., WGS72)` uses to read the mean motion)
_RE_WGS72_KM = WGS72_RE_M / 1e3
_MU_WGS72_KM3PS2 = WGS72_MU_M3PS2 / 1e9
_XKE_PER_MIN = 60.0 / math.sqrt(_RE_WGS72_KM**3 / _MU_WGS72_KM3PS2)
_J2_WGS72 = WGS72_J2
_ECCENTRICITY = 1e-4

GPS_NORAD_BASE = 90000
STARLINK_NORAD_BASE = 90100


@dataclass(frozen=True)
class WalkerShell:
    """One Walker-delta shell: altitude (km), inclination (deg), planes, satellites per plane.

    `filed_per_plane` is the filed number per plane when the generator fills fewer slots.
    """

    label: str
    altitude_km: float
    inclination_deg: float
    planes: int
    per_plane: int
    phasing: int = 1
    filed_per_plane: int | None = None

    @property
    def total(self) -> int:
        return self.planes * self.per_plane


# Starlink shells as filed with the FCC:
# - Gen1, modification granted in FCC 21-48 (April 2021, SAT-MOD-20200417-00037):
#   550 km 53.0 deg 72x22; 540 km 53.2 deg 72x22; 570 km 70 deg 36x20;
#   560 km 97.6 deg 6x58 and 4x43 (4,408 satellites).
# - Gen2 partial grant FCC 22-91 (December 2022, SAT-LOA-20200526-00055), 7,500 of the
#   shells 525 km 53 deg, 530 km 43 deg, 535 km 33 deg, each 28 planes x 120.
# Filled here to 9,616 satellites, like the ~9,500 on orbit in early 2026 (CelesTrak
# 'starlink' group 2026-02-23: 9,543): Gen1 complete, Gen2 43 deg complete, Gen2 53 deg at
# 66 of 120 slots per plane, none at 33 deg. The phasing factor F is not in the filings;
# F = 1 is our choice.
STARLINK_SHELLS: tuple[WalkerShell, ...] = (
    WalkerShell("gen1-53.0", 550.0, 53.0, 72, 22),
    WalkerShell("gen1-53.2", 540.0, 53.2, 72, 22),
    WalkerShell("gen1-70", 570.0, 70.0, 36, 20),
    WalkerShell("gen1-97.6a", 560.0, 97.6, 6, 58),
    WalkerShell("gen1-97.6b", 560.0, 97.6, 4, 43),
    WalkerShell("gen2-43", 530.0, 43.0, 28, 120),
    WalkerShell("gen2-53", 525.0, 53.0, 28, 66, filed_per_plane=120),
)

# GPS: 6 orbital planes A-F, 55 deg, a = 26,559.7 km (IS-GPS-200 / SPS performance
# standard nominal), 31 operational satellites as in 2026: plane A holds 6, the others 5.
GPS_SEMI_MAJOR_AXIS_KM = 26559.7
GPS_INCLINATION_DEG = 55.0
GPS_PLANE_COUNTS = (6, 5, 5, 5, 5, 5)


def kozai_mean_motion_revday(semi_major_axis_km: float, inclination_deg: float,
                             eccentricity: float = _ECCENTRICITY) -> float:
    """TLE (Kozai) mean motion, rev/day, for which SGP4 recovers the given mean semi-major axis."""
    a_er = semi_major_axis_km / _RE_WGS72_KM
    n_brouwer = _XKE_PER_MIN / a_er**1.5  # rad/min
    cosi = math.cos(math.radians(inclination_deg))
    d1 = 0.75 * _J2_WGS72 * (3.0 * cosi * cosi - 1.0) / (1.0 - eccentricity**2) ** 1.5
    n_kozai = n_brouwer
    for _ in range(20):  # fixed point of n_kozai = n_brouwer (1 + del(n_kozai))
        ak = (_XKE_PER_MIN / n_kozai) ** (2.0 / 3.0)
        delta = d1 / (ak * ak)
        adel = ak * (1.0 - delta * delta - delta * (1.0 / 3.0 + 134.0 * delta * delta / 81.0))
        delta = d1 / (adel * adel)
        n_next = n_brouwer * (1.0 + delta)
        if abs(n_next - n_kozai) < 1e-15:
            break
        n_kozai = n_next
    return n_kozai * 1440.0 / (2.0 * math.pi)


def _entry(name: str, norad_id: int, epoch: _dt.datetime, mean_motion_revday: float, incl_deg: float,
           raan_deg: float, mean_anomaly_deg: float) -> str:
    line1, line2 = format_tle(
        norad_id=norad_id, epoch_utc=epoch, inclination_deg=incl_deg, raan_deg=raan_deg,
        eccentricity=_ECCENTRICITY, arg_perigee_deg=0.0, mean_anomaly_deg=mean_anomaly_deg,
        mean_motion_revday=mean_motion_revday,
    )
    return f"{name:<24s}\n{line1}\n{line2}\n"


def walker_tle(shells: tuple[WalkerShell, ...], epoch_utc: _dt.datetime, *, name_prefix: str,
               norad_base: int) -> str:
    """3LE text of Walker-delta shells at `epoch_utc` (one serial number across shells)."""
    epoch = as_utc(epoch_utc)
    parts = [f"# leonav generated Walker-delta constellation, epoch {epoch.isoformat()}\n"]
    serial = 0
    for shell in shells:
        filed = f", filed {shell.planes}x{shell.filed_per_plane}" if shell.filed_per_plane else ""
        parts.append(f"# shell {shell.label}: {shell.altitude_km:g} km, {shell.inclination_deg:g} deg, "
                     f"{shell.planes} planes x {shell.per_plane}{filed}, F={shell.phasing}\n")
        # one mean motion per shell: its fixed-point iteration is a third of the text's cost
        n_revday = kozai_mean_motion_revday(R_EQUATOR_KM + shell.altitude_km, shell.inclination_deg)
        for j in range(shell.planes):
            for k in range(shell.per_plane):
                serial += 1
                raan = 360.0 * j / shell.planes
                anomaly = 360.0 * k / shell.per_plane + 360.0 * shell.phasing * j / shell.total
                name = f"{name_prefix}{round(shell.inclination_deg):02d}-{serial:04d}"
                parts.append(_entry(name, norad_base + serial - 1, epoch, n_revday, shell.inclination_deg,
                                    raan, anomaly))
    if norad_base + serial - 1 > 99999:
        raise ValueError("generated NORAD ids exceed the 5-digit range")
    return "".join(parts)


def starlink_walker_tle(epoch_utc: _dt.datetime) -> str:
    """3LE text of a 9,616-satellite Starlink-like constellation (`STARLINK_SHELLS`) at the epoch."""
    return walker_tle(STARLINK_SHELLS, epoch_utc, name_prefix="STARLINK-W", norad_base=STARLINK_NORAD_BASE)


def gps_walker_tle(epoch_utc: _dt.datetime) -> str:
    """3LE text of a 31-satellite GPS-like constellation: planes A-F, 55 deg, a = 26,559.7 km."""
    epoch = as_utc(epoch_utc)
    parts = [f"# leonav generated GPS-like constellation, epoch {epoch.isoformat()}: 6 planes, "
             f"{GPS_INCLINATION_DEG:g} deg, a = {GPS_SEMI_MAJOR_AXIS_KM:g} km\n"]
    total = sum(GPS_PLANE_COUNTS)
    n_revday = kozai_mean_motion_revday(GPS_SEMI_MAJOR_AXIS_KM, GPS_INCLINATION_DEG)
    prn = 0
    for j, count in enumerate(GPS_PLANE_COUNTS):
        for k in range(count):
            prn += 1
            plane = "ABCDEF"[j]
            raan = 60.0 * j
            anomaly = 360.0 * k / count + 360.0 * j / total
            parts.append(_entry(f"GPS-W {plane}{k + 1} (PRN {prn:02d})", GPS_NORAD_BASE + prn - 1, epoch,
                                n_revday, GPS_INCLINATION_DEG, raan, anomaly))
    return "".join(parts)


def default_elements(epoch_utc: _dt.datetime) -> dict[str, ElementSet]:
    """{'gps': ..., 'starlink': ...} generated at `epoch_utc` (elements of age zero)."""
    return {
        "gps": parse_elements_text(gps_walker_tle(epoch_utc), "<leonav gps walker>", constellation="gps"),
        "starlink": parse_elements_text(starlink_walker_tle(epoch_utc), "<leonav starlink walker>",
                                        constellation="starlink"),
    }


def group_by_constellation(element_sets: list[ElementSet]) -> dict[str, ElementSet]:
    """Concatenate element sets per constellation ("starlink", "gps", "unknown"), in order."""
    out: dict[str, ElementSet] = {}
    for es in element_sets:
        name = (es.constellation or "unknown").lower()
        out[name] = out[name].concat(es) if name in out else es
    return out
