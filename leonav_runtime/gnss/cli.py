"""`leonav gnss`: look at GNSS inputs (RINEX files, u-blox logs, GPS element sets).

    leonav gnss nav FILE...            ephemerides per system, rejected records (file:line: field: why)
    leonav gnss obs FILE [--nav NAV]   observation table summary; with --nav, satellite-state counts
    leonav gnss ubx LOG [--week W]     RAWX rows and SFRBX ephemerides of a u-blox log
    leonav gnss tle-vs-brdc TLE NAV    TLE (SGP4) minus broadcast orbit table (RTN RMS / max, m)

Read-only: prints to the terminal and writes no results folder.
"""
from __future__ import annotations

import argparse
import json
from collections import Counter


def _nav(args) -> int:
    from leonav_runtime.gnss.rinex_nav import read_rinex_nav

    for path in args.files:
        nav = read_rinex_nav(path)
        eph = nav.ephemerides
        print(f"{path}: RINEX {nav.version:.2f}, {len(eph)} ephemerides "
              f"{dict(sorted(Counter(eph['system'].tolist()).items()))}, {len(eph.satellites())} satellites, "
              f"counts {dict(sorted(eph.counts.items()))}")
        for rej in eph.rejected[: args.max_rejections]:
            print(f"  rejected {rej}")
    return 0


def _obs(args) -> int:
    from leonav_runtime.gnss.rinex_nav import read_rinex_navs
    from leonav_runtime.gnss.rinex_obs import read_rinex_obs
    from leonav_runtime.gnss.sat_states import states_for_observations

    obs = read_rinex_obs(args.file)
    summary = obs.summary()
    if args.nav:
        st = states_for_observations(obs, read_rinex_navs(args.nav))
        summary["satellite_states"] = dict(st.counts)
    print(json.dumps(summary, indent=1))
    for rej in obs.rejected[: args.max_rejections]:
        print(f"  rejected {rej}")
    return 0


def _ubx(args) -> int:
    from leonav_runtime.gnss.ubx_log import read_ubx_log

    log = read_ubx_log(args.file, reference_week=args.week)
    print(json.dumps({"observations": log.observations.summary(), "ephemerides": len(log.ephemerides),
                      "frames": dict(sorted(log.counts.items()))}, indent=1))
    return 0


def _tle(args) -> int:
    from leonav_runtime.gnss.tle_vs_broadcast import compare, format_table

    print(format_table(compare(args.tle, args.nav, step_s=args.step).stats()))
    return 0


def register(subparsers) -> None:
    p = subparsers.add_parser("gnss", help="inspect RINEX navigation/observation files, u-blox logs, TLE vs broadcast",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="gnss_command", metavar="WHAT", required=True)
    n = sub.add_parser("nav", help="RINEX navigation files")
    n.add_argument("files", nargs="+", metavar="FILE", help="RINEX 2 or 3 navigation file(s)")
    n.add_argument("--max-rejections", type=int, default=20, metavar="N",
                   help="rejected records to list per file, count (default 20; all are counted)")
    n.set_defaults(func=_nav)
    o = sub.add_parser("obs", help="a RINEX observation file")
    o.add_argument("file", metavar="FILE", help="RINEX 2 or 3 observation file")
    o.add_argument("--nav", nargs="*", default=[], metavar="NAV",
                   help="RINEX navigation file(s): also count the satellite states they give per epoch")
    o.add_argument("--max-rejections", type=int, default=20, metavar="N",
                   help="rejected lines to list, count (default 20; all are counted)")
    o.set_defaults(func=_obs)
    u = sub.add_parser("ubx", help="a u-blox log (RXM-RAWX, RXM-SFRBX)")
    u.add_argument("file", metavar="LOG", help="u-blox binary log (UBX frames, NMEA interleaved allowed)")
    u.add_argument("--week", type=int, default=None, help="reference GPS week for the 10-bit LNAV week")
    u.set_defaults(func=_ubx)
    t = sub.add_parser("tle-vs-brdc", help="TLE minus broadcast orbits of GPS satellites")
    t.add_argument("tle", metavar="TLE", help="GPS element sets (TLE/3LE text, e.g. CelesTrak's gps-ops group)")
    t.add_argument("nav", metavar="NAV", help="RINEX GPS navigation file of the same days")
    t.add_argument("--step", type=float, default=300.0, metavar="S",
                   help="comparison time step, s (default 300)")
    t.set_defaults(func=_tle)
