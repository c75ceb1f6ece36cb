"""How far are SGP4/TLE orbits of GPS satellites from their broadcast orbits?

For each GPS satellite with both a TLE (names "Gnn" or "... (PRN nn)") and a broadcast
ephemeris, positions are compared on a time grid over the navigation file's day:
SGP4 through `leonav_runtime.orbits.propagate_ecef` (TEME -> ECEF with the IERS Earth
orientation) at UTC = GPST - (GPS-UTC leap seconds), the broadcast orbit through
`leonav_runtime.orbits.broadcast` at GPST, both in ECEF. The difference TLE - broadcast
is split into radial, along-track and cross-track components of the broadcast orbit
(along-track from the inertial velocity v_ecef + w x r).

`python -m leonav_runtime.gnss.tle_vs_broadcast TLE NAV [--step S]` prints the table.
"""
from __future__ import annotations

import argparse
import re
import sys
import warnings
from dataclasses import dataclass

import numpy as np

from leonav_runtime.gen.constants import GPS_OMEGA_E_RADPS
from leonav_runtime.gnss import time as gtime
from leonav_runtime.gnss.ephemeris import OK, Ephemerides
from leonav_runtime.gnss.rinex_nav import read_rinex_nav
from leonav_runtime.orbits import load_elements, propagate_ecef
from leonav_runtime.orbits.broadcast import satellite_states

_PRN_PATTERNS = (re.compile(r"^G(\d{2})$"), re.compile(r"PRN\s*(\d{1,2})\)?\s*$"))


def gps_prn_from_name(name: str) -> int | None:
    """PRN from a TLE name like "G05" or "GPS BIIRM-8 (PRN 05)"; None otherwise."""
    for pat in _PRN_PATTERNS:
        m = pat.search(name.strip())
        if m:
            return int(m.group(1))
    return None


@dataclass
class RtnErrors:
    """Per satellite (PRNs) and epoch: radial/along/cross TLE-minus-broadcast errors (m)."""

    prns: np.ndarray
    t_gps_s: np.ndarray
    rtn_m: np.ndarray          # (nsat, nt, 3), NaN where either orbit is missing
    tle_age_days: np.ndarray   # (nsat,) at the start of the grid (positive: TLE older)

    def stats(self) -> list[dict]:
        """Rows of RMS / max |.| per component and 3-D, per satellite and 'all'."""
        rows = []

        def one(label, e, age):
            ok = np.isfinite(e).all(axis=-1)
            e = e[ok]
            if e.size == 0:
                return
            norm = np.linalg.norm(e, axis=-1)
            rows.append({"sat": label, "n": int(ok.sum()), "tle_age_d": age,
                         "rms_r_m": float(np.sqrt(np.mean(e[:, 0] ** 2))), "rms_a_m": float(np.sqrt(np.mean(e[:, 1] ** 2))),
                         "rms_c_m": float(np.sqrt(np.mean(e[:, 2] ** 2))), "rms_3d_m": float(np.sqrt(np.mean(norm**2))),
                         "max_r_m": float(np.max(np.abs(e[:, 0]))), "max_a_m": float(np.max(np.abs(e[:, 1]))),
                         "max_c_m": float(np.max(np.abs(e[:, 2]))), "max_3d_m": float(np.max(norm))})

        for k, prn in enumerate(self.prns):
            one(f"G{prn:02d}", self.rtn_m[k], float(self.tle_age_days[k]))
        one("all", self.rtn_m.reshape(-1, 3), float(np.mean(self.tle_age_days)))
        return rows


def compare(tle_path, nav_path, *, step_s: float = 300.0, t0_gps_s: float | None = None,
            span_s: float = 86400.0) -> RtnErrors:
    """TLE-minus-broadcast errors of every GPS satellite present in both files."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # stale-element warnings: the age is reported instead
        elements = load_elements(tle_path, stale_after_days=30.0)
    nav: Ephemerides = read_rinex_nav(nav_path).ephemerides
    prn_of = [gps_prn_from_name(n) for n in elements.names]
    have = {p for s, p in nav.satellites() if s == "G"}
    pick = [i for i, p in enumerate(prn_of) if p is not None and p in have]
    # one TLE per PRN (the first in the file)
    seen: dict[int, int] = {}
    for i in pick:
        seen.setdefault(prn_of[i], i)
    prns = np.array(sorted(seen))
    idx = [seen[p] for p in prns]
    es = elements.select(idx)
    if t0_gps_s is None:  # the UTC-day start of the navigation data's first toc, in GPST
        first = float(np.min(nav["toc"]))
        t0_gps_s = np.floor(first / 86400.0) * 86400.0
    t = t0_gps_s + np.arange(0.0, span_s + 1e-9, step_s)
    epoch_utc = gtime.gps_seconds_to_utc(float(t[0]))
    states = propagate_ecef(es, epoch_utc, t - t[0], acceleration=False, warn_stale=False)
    r_tle = states.r_ecef_m
    nsat, nt = len(prns), t.size
    rtn = np.full((nsat, nt, 3), np.nan)
    for k, prn in enumerate(prns):
        index, status = nav.select("G", int(prn), t)
        ok = status == OK
        if not ok.any():
            continue
        st = satellite_states(nav.data[index[ok]], t[ok])
        r, v = st.r_ecef_m, st.v_ecef_mps
        v_inertial = v + np.cross([0.0, 0.0, GPS_OMEGA_E_RADPS], r)
        e_r = r / np.linalg.norm(r, axis=-1, keepdims=True)
        e_c = np.cross(r, v_inertial)
        e_c /= np.linalg.norm(e_c, axis=-1, keepdims=True)
        e_a = np.cross(e_c, e_r)
        d = r_tle[k, ok] - r
        rtn[k, ok] = np.stack([(d * e_r).sum(-1), (d * e_a).sum(-1), (d * e_c).sum(-1)], axis=-1)
    ages = es.ages_s(epoch_utc) / 86400.0
    return RtnErrors(prns, t, rtn, ages)


def format_table(rows: list[dict]) -> str:
    head = (f"{'sat':>4} {'n':>4} {'age_d':>6} | {'rms R':>7} {'rms A':>8} {'rms C':>7} {'rms 3D':>8} | "
            f"{'max R':>7} {'max A':>8} {'max C':>7} {'max 3D':>8}   (m)")
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(f"{r['sat']:>4} {r['n']:>4} {r['tle_age_d']:>6.2f} | {r['rms_r_m']:>7.0f} {r['rms_a_m']:>8.0f} "
                     f"{r['rms_c_m']:>7.0f} {r['rms_3d_m']:>8.0f} | {r['max_r_m']:>7.0f} {r['max_a_m']:>8.0f} "
                     f"{r['max_c_m']:>7.0f} {r['max_3d_m']:>8.0f}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m leonav_runtime.gnss.tle_vs_broadcast", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("tle")
    parser.add_argument("nav")
    parser.add_argument("--step", type=float, default=300.0, help="grid step, s [300]")
    args = parser.parse_args(argv)
    errors = compare(args.tle, args.nav, step_s=args.step)
    print(format_table(errors.stats()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
