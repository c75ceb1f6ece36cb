"""GLONASS broadcast ephemerides from u-blox RXM-SFRBX strings, and their orbits.

Interface Control Document GLONASS, edition 5.1 (2008), section 4.4 (navigation message,
strings of 85 bits, bit 85 first: an idle 0, then the string number m in bits 84-81) and
Appendix A.3.1.2 (satellite motion between ephemeris epochs).

u-blox RXM-SFRBX for GLONASS (gnssId 6, svId = the orbital slot, freqId = k + 7): four U4
words; the 85 string bits run from bit 31 of the first word on (words 1-2 whole, 21 bits of
word 3, the rest zero); the fourth word holds the receiver's superframe and frame number
(`frame_key`), which tells which strings belong to one 30-s frame.

Immediate data (strings 1-4 of one frame), ICD Table 4.5, sign-magnitude where signed:
string 1: tk (h 5 bits, min 6, 30 s 1) bits 76-65, x' 64-41 (2^-20 km/s), x'' 40-36
(2^-30 km/s^2), x 35-9 (2^-11 km); string 2: Bn 80-78, tb 76-70 (15 min), y', y'', y;
string 3: gamma_n 79-69 (2^-40), ln 65, z', z'', z; string 4: tau_n 80-59 (2^-30 s),
delta tau_n 58-54, En 53-49 (days), NT 26-16 (day in the four-year interval), n 15-11 (slot).
tb and tk are Moscow time, UTC(SU) + 3 h; positions are PZ-90 (within decimetres of WGS 84
since PZ-90.11, far below what the uses here need). The Hamming check bits (8-1) are not
checked; a frame is used only when its strings 1-4 arrived in one frame and string 4 names
the same slot as svId.

Orbit (`state_at`): the ICD's equations in the Earth-fixed frame (central body, J2, Earth
rotation terms, the broadcast luni-solar accelerations held constant), fourth-order
Runge-Kutta from tb in steps of at most 60 s (the ICD's integration interval is +-15 min).
"""
from __future__ import annotations

import dataclasses
import datetime as _dt
import math
from collections import Counter

import numpy as np

GM_M3PS2 = 398600.4418e9        # PZ-90 gravitational constant
AE_M = 6378136.0                # PZ-90 equatorial radius
J2 = 1082625.75e-9              # second zonal harmonic
OMEGA_E_RADPS = 7.2921150e-5    # Earth rotation rate (ICD)
MOSCOW_OFFSET_S = 3 * 3600.0    # GLONASS time = UTC(SU) + 3 h
STEP_S = 60.0                   # RK4 step
GLONASS_ID = 6                  # u-blox gnssId


@dataclasses.dataclass
class GlonassEphemeris:
    """One immediate-data set: slot, frequency number k, tb (UTC, datetime), r_m / v_mps /
    a_mps2 (3,) PZ-90 at tb, gamma_n, tau_n_s, Bn (health, 0 = healthy), En (age, days), NT."""

    slot: int
    k: int
    tb_utc: _dt.datetime
    r_m: np.ndarray
    v_mps: np.ndarray
    a_mps2: np.ndarray
    gamma_n: float
    tau_n_s: float
    health: int
    age_days: int
    nt: int


def _string_bits(words) -> str:
    """The 85 string bits of an SFRBX GLONASS payload's words, bit 85 first."""
    return "".join(f"{w & 0xFFFFFFFF:032b}" for w in words[:3])[:85]


def _u(s: str, start: int, n: int) -> int:
    return int(s[start:start + n], 2)


def _sm(s: str, start: int, n: int) -> int:
    """Sign-magnitude field: the first bit is the sign."""
    v = int(s[start + 1:start + n], 2)
    return -v if s[start] == "1" else v


def string_number(words) -> int:
    """String number m of a GLONASS string (bits 84-81)."""
    return _u(_string_bits(words), 1, 4)


def frame_key(words) -> int:
    """The fourth word: superframe and frame number the receiver puts with the string."""
    return int(words[3]) if len(words) > 3 else -1


def _axis(s: str) -> tuple[float, float, float]:
    """(position m, velocity m/s, acceleration m/s^2) of one axis from strings 1-3."""
    return _sm(s, 50, 27) * 2.0**-11 * 1e3, _sm(s, 21, 24) * 2.0**-20 * 1e3, _sm(s, 45, 5) * 2.0**-30 * 1e3


def tb_utc(tb_index: int, reference_utc: _dt.datetime) -> _dt.datetime:
    """UTC of tb (15-min units of the Moscow day) on the Moscow day that puts it nearest
    `reference_utc` (the strings carry the day only as NT; the receiver's time is at hand)."""
    ref = reference_utc.astimezone(_dt.timezone.utc)
    moscow = ref + _dt.timedelta(seconds=MOSCOW_OFFSET_S)
    day0 = _dt.datetime(moscow.year, moscow.month, moscow.day, tzinfo=_dt.timezone.utc)
    best = None
    for d in (-1, 0, 1):
        t = day0 + _dt.timedelta(days=d, seconds=tb_index * 900.0 - MOSCOW_OFFSET_S)
        if best is None or abs((t - ref).total_seconds()) < abs((best - ref).total_seconds()):
            best = t
    return best


def decode_frame(strings: dict[int, list[int]], sv_id: int, freq_id: int,
                 reference_utc: _dt.datetime) -> GlonassEphemeris | None:
    """Ephemeris of strings 1-4 (words by string number) of one frame, or None when the
    slot in string 4 is not svId."""
    s1, s2, s3, s4 = (_string_bits(strings[m]) for m in (1, 2, 3, 4))
    slot = _u(s4, 70, 5)
    if slot != sv_id:
        return None
    axes = [_axis(s) for s in (s1, s2, s3)]
    return GlonassEphemeris(
        slot=slot, k=freq_id - 7, tb_utc=tb_utc(_u(s2, 9, 7), reference_utc),
        r_m=np.array([a[0] for a in axes]), v_mps=np.array([a[1] for a in axes]),
        a_mps2=np.array([a[2] for a in axes]), gamma_n=_sm(s3, 6, 11) * 2.0**-40,
        tau_n_s=_sm(s4, 5, 22) * 2.0**-30, health=_u(s2, 5, 3) >> 2, age_days=_u(s4, 32, 5), nt=_u(s4, 59, 11))


def ephemerides_from_sfrbx(frames, reference_utc: _dt.datetime) -> tuple[list[GlonassEphemeris], Counter]:
    """GLONASS ephemerides of parsed SFRBX frames (`sfrbx.parse_sfrbx_payload` results, in
    arrival order): one per frame whose strings 1-4 all arrived, repeats of the same tb and
    slot kept once. Counts strings, frames used, and frames dropped by reason."""
    counts: Counter = Counter()
    pending: dict[tuple[int, int], dict[int, list[int]]] = {}
    out: dict[tuple[int, _dt.datetime], GlonassEphemeris] = {}
    for f in frames:
        if f.gnss_id != GLONASS_ID:
            continue
        if len(f.words) < 4:
            counts["short_string"] += 1
            continue
        counts["strings"] += 1
        m = string_number(f.words)
        key = (f.sv_id, frame_key(f.words))
        if m in (1, 2, 3, 4):
            pending.setdefault(key, {})[m] = list(f.words)
        got = pending.get(key, {})
        if m == 4 and all(n in got for n in (1, 2, 3, 4)):
            eph = decode_frame(pending.pop(key), f.sv_id, f.freq_id, reference_utc)
            if eph is None:
                counts["slot_mismatch"] += 1
                continue
            counts["frames"] += 1
            out.setdefault((eph.slot, eph.tb_utc), eph)
    counts["ephemerides"] = len(out)
    return sorted(out.values(), key=lambda e: (e.slot, e.tb_utc)), counts


def _derivative(y: np.ndarray, acc: np.ndarray) -> np.ndarray:
    """ICD Appendix A.3.1.2: d/dt [r, v] in the Earth-fixed PZ-90 frame."""
    x, yy, z, vx, vy, vz = y
    r2 = x * x + yy * yy + z * z
    r = math.sqrt(r2)
    mu = GM_M3PS2 / (r2 * r)
    j = 1.5 * J2 * GM_M3PS2 * AE_M**2 / (r2 * r2 * r)
    z2 = 5.0 * z * z / r2
    w2 = OMEGA_E_RADPS**2
    ax = -mu * x - j * x * (1.0 - z2) + w2 * x + 2.0 * OMEGA_E_RADPS * vy + acc[0]
    ay = -mu * yy - j * yy * (1.0 - z2) + w2 * yy - 2.0 * OMEGA_E_RADPS * vx + acc[1]
    az = -mu * z - j * z * (3.0 - z2) + acc[2]
    return np.array([vx, vy, vz, ax, ay, az])


def state_at(eph: GlonassEphemeris, t_utc: _dt.datetime) -> tuple[np.ndarray, np.ndarray]:
    """Position (m) and velocity (m/s), PZ-90 Earth-fixed, at t_utc (RK4 from tb)."""
    dt_total = (t_utc - eph.tb_utc).total_seconds()
    y = np.r_[eph.r_m, eph.v_mps]
    n = max(1, int(math.ceil(abs(dt_total) / STEP_S)))
    h = dt_total / n
    for _ in range(n):
        k1 = _derivative(y, eph.a_mps2)
        k2 = _derivative(y + 0.5 * h * k1, eph.a_mps2)
        k3 = _derivative(y + 0.5 * h * k2, eph.a_mps2)
        k4 = _derivative(y + h * k3, eph.a_mps2)
        y = y + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return y[:3], y[3:]


def nearest(ephs: list[GlonassEphemeris], slot: int, t_utc: _dt.datetime) -> GlonassEphemeris | None:
    """The slot's ephemeris with tb nearest t_utc, or None."""
    cand = [e for e in ephs if e.slot == slot]
    return min(cand, key=lambda e: abs((e.tb_utc - t_utc).total_seconds())) if cand else None
