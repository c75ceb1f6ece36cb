"""Test helper: RINEX 3.03 navigation and observation text written from Python values
(Galileo, BeiDou MEO and GEO, GPS, and a GLONASS record that readers must skip).

The shared data holds no RINEX 3 file, so the Galileo/BeiDou paths are checked on text
made here, with element values typical of each system's broadcast orbits; RTKLIB reads
the same text (tests/test_gnss_rtklib.py)."""
from __future__ import annotations

from leonav_runtime.gnss import time as gtime


def _d(v: float) -> str:
    return f"{v:19.12E}".replace("E", "D")


def nav_record(sys_prn: str, epoch: tuple, clock: tuple, lines: list[tuple]) -> str:
    y, mo, d, h, mi, s = epoch
    out = [f"{sys_prn} {y:04d} {mo:02d} {d:02d} {h:02d} {mi:02d} {s:02d}" + "".join(_d(v) for v in clock)]
    for vals in lines:
        out.append("    " + "".join(_d(v) for v in vals))
    return "\n".join(out)


def header_line(text: str, label: str) -> str:
    return f"{text:<60}{label}"


# toe = toc = 2020-06-02 02:00:00 in each system's own time scale
EPOCH = (2020, 6, 2, 2, 0, 0)
T_TOE_SYS = gtime.calendar_to_seconds(*EPOCH)
TOE_SOW = T_TOE_SYS % 604800.0
GPS_WEEK = int(T_TOE_SYS // 604800)
BDT_WEEK = GPS_WEEK - 1356


def _orbit(sqrt_a, e, i0, omega0, omega, m0, week, *, line6_mid=0.0, line7=(3.0, 0.0, -5.1e-9, -5.8e-9),
           line8=None, iode=45.0):
    line8 = line8 if line8 is not None else (TOE_SOW - 1800.0, 0.0, 0.0, 0.0)
    return [
        (iode, -45.6875, 4.1e-9, m0),
        (-2.4e-6, e, 7.5e-6, sqrt_a),
        (TOE_SOW, 1.1e-7, omega0, -7.4e-8),
        (i0, 230.5, omega, -8.1e-9),
        (2.3e-10, line6_mid, week, 0.0),
        line7,
        line8,
    ]


def nav_text() -> str:
    head = [
        header_line("     3.03           N: GNSS NAV DATA    M: MIXED", "RINEX VERSION / TYPE"),
        header_line("leonav test        leonav              20200602 000000 UTC", "PGM / RUN BY / DATE"),
        header_line("    18", "LEAP SECONDS"),
        header_line("", "END OF HEADER"),
    ]
    recs = [
        nav_record("E11", EPOCH, (-6.2e-4, -7.8e-12, 0.0),
                   _orbit(5440.61, 2.1e-4, 0.9703, -1.1, 0.42, 2.31, GPS_WEEK, line6_mid=517.0,
                          line7=(3.12, 0.0, 1.2e-9, 1.4e-9), iode=88.0)),
        nav_record("E12", EPOCH, (2.0e-4, 1.1e-12, 0.0),
                   _orbit(5440.59, 3.5e-4, 0.9690, 1.2, -0.8, -1.7, GPS_WEEK, line6_mid=258.0,
                          line7=(3.12, 0.0, -2.0e-9, -2.3e-9), iode=88.0)),
        nav_record("C11", EPOCH, (3.1e-4, 4.4e-11, 0.0),
                   _orbit(5282.62, 1.6e-3, 0.9599, 2.6, -2.9, 0.77, BDT_WEEK,
                          line7=(2.0, 0.0, 4.3e-9, -1.6e-9), line8=(TOE_SOW - 1800.0, 1.0, 0.0, 0.0), iode=1.0)),
        nav_record("C01", EPOCH, (-4.5e-4, 3.9e-11, 0.0),
                   _orbit(6493.45, 5.2e-4, 0.0851, -2.98, -0.33, 1.55, BDT_WEEK,
                          line7=(2.0, 0.0, -5.8e-9, -5.8e-9), line8=(TOE_SOW - 1800.0, 1.0, 0.0, 0.0), iode=1.0)),
        nav_record("G05", EPOCH, (-1.3e-4, -5.2e-12, 0.0),
                   _orbit(5153.65, 5.4e-3, 0.9553, -0.55, 0.91, -2.44, GPS_WEEK,
                          line6_mid=1.0, line7=(2.0, 0.0, -1.1e-8, 261.0), line8=(TOE_SOW - 1800.0, 4.0, 0.0, 0.0),
                          iode=5.0)),
        "R03 2020 06 02 01 45 00" + "".join(_d(v) for v in (1.0e-5, 0.0, 5.4e3)) + "\n" +
        "\n".join("    " + "".join(_d(v) for v in (1.0e4, 1.0, 0.0, 0.0)) for _ in range(3)),
    ]
    return "\n".join(head + recs) + "\n"


# receive epochs (GPST) and satellites for the observation file
OBS_EPOCHS = ((2020, 6, 2, 1, 30, 0.0), (2020, 6, 2, 2, 0, 0.0), (2020, 6, 2, 2, 45, 30.0))
OBS_SATS = (("E11", "C1C", 23_512_345.678), ("E12", "C1C", 25_912_345.678), ("C11", "C2I", 22_812_345.678),
            ("C01", "C2I", 37_912_345.678), ("G05", "C1C", 21_012_345.678))


def obs_text() -> str:
    head = [
        header_line("     3.03           OBSERVATION DATA    M: MIXED", "RINEX VERSION / TYPE"),
        header_line("leonav test        leonav              20200602 000000 UTC", "PGM / RUN BY / DATE"),
        header_line("TEST", "MARKER NAME"),
        header_line(f"{-3947762.7496:14.4f}{3364399.8789:14.4f}{3699428.5111:14.4f}", "APPROX POSITION XYZ"),
        header_line("        0.0000        0.0000        0.0000", "ANTENNA: DELTA H/E/N"),
        header_line("G    2 C1C D1C", "SYS / # / OBS TYPES"),
        header_line("E    2 C1C D1C", "SYS / # / OBS TYPES"),
        header_line("C    2 C2I D2I", "SYS / # / OBS TYPES"),
        header_line("  2020     6     2     1    30    0.0000000     GPS", "TIME OF FIRST OBS"),
        header_line("", "END OF HEADER"),
    ]
    body = []
    for (y, mo, d, h, mi, s) in OBS_EPOCHS:
        body.append(f"> {y:04d} {mo:02d} {d:02d} {h:02d} {mi:02d}{s:11.7f}  0{len(OBS_SATS):3d}")
        for sat, _code, pr in OBS_SATS:
            body.append(f"{sat}{pr:14.3f}  {-1234.567:14.3f}  ")
    return "\n".join(head + body) + "\n"
