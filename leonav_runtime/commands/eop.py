"""`leonav eop`: the Earth orientation parameters in use for a date.

    leonav eop [--date ISO-UTC] [--days N] [--json]

Prints UT1-UTC and polar motion from the IERS table every TEME -> ECEF conversion uses
(SGP4 for Starlink and GPS, the beacon predictions, the simulator, replay), whether the
values are measured or predicted, and the table's source and version. Read-only: it writes
no results folder.
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import math
import warnings

import numpy as np

from leonav_runtime.common.utc import parse_utc


def eop_report(date_utc: _dt.datetime, days: int = 1) -> dict:
    """EOP at `date_utc` and the following `days - 1` days at 0h steps of one day (JSON-ready)."""
    from leonav_runtime.orbits import eop

    table = eop.default_table()
    t_s = np.arange(max(int(days), 1)) * 86400.0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", eop.StaleEopWarning)
        values = table.at(date_utc, t_s)
    rows = []
    for k, t in enumerate(t_s):
        rows.append({
            "utc": (date_utc + _dt.timedelta(seconds=float(t))).isoformat(),
            "ut1_utc_s": float(values.ut1_utc_s[k]),
            "xp_arcsec": float(values.xp_rad[k] / eop.ARCSEC_RAD),
            "yp_arcsec": float(values.yp_rad[k] / eop.ARCSEC_RAD),
            "kind": "IERS prediction" if values.predicted[k] else "IERS measured (Bulletin A)",
        })
    first, last = eop.mjd_to_utc(table.mjd[0]), eop.mjd_to_utc(table.mjd[-1])
    return {
        "table": table.source,
        "astropy_iers_data_version": eop.table_version(),
        "table_span_utc": [first.date().isoformat(), last.date().isoformat()],
        "last_measured_utc": eop.mjd_to_utc(table.last_measured_mjd).date().isoformat(),
        "rejected_lines": table.rejected_lines,
        "values": rows,
        "warnings": [str(w.message) for w in caught],
    }


def _run(args: argparse.Namespace) -> int:
    if args.date:
        date = parse_utc(args.date, "--date", require_zone=True)
    else:  # now, to the second, printed with its offset like a --date
        date = _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0)
    report = eop_report(date, args.days)
    if args.json:
        print(json.dumps(report, indent=1))
        return 0
    version = f" (astropy-iers-data {report['astropy_iers_data_version']})" if report["astropy_iers_data_version"] else ""
    print(f"EOP table {report['table']}{version}")
    print(f"  rows {report['table_span_utc'][0]} .. {report['table_span_utc'][1]}, "
          f"measured up to {report['last_measured_utc']}, predictions after")
    width = max(26, *(len(r["utc"]) + 1 for r in report["values"]))  # the whole time, offset included
    print(f"{'UTC':<{width}} {'UT1-UTC s':>11} {'x_p arcsec':>11} {'y_p arcsec':>11}  kind")
    for r in report["values"]:
        print(f"{r['utc']:<{width}} {r['ut1_utc_s']:>11.7f} {r['xp_arcsec']:>11.6f} {r['yp_arcsec']:>11.6f}  {r['kind']}")
    east_m = report["values"][0]["ut1_utc_s"] * 7.292115e-5 * 6378137.0 * math.cos(math.radians(43.08))
    print(f"ignoring UT1-UTC would move a receiver at 43 deg latitude {east_m:+.1f} m east as seen from orbit")
    import logging

    for w in report["warnings"]:   # `leonav eop: warning: ...` on stderr, silenced by -q
        logging.getLogger("leonav.eop").warning(w)
    return 0


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "eop", help="Earth orientation (UT1-UTC, polar motion) in use for a date",
        description=__doc__.split("\n\n")[0] + ". Source: the IERS finals2000A table of the installed "
        "astropy-iers-data package (update: pip install -U astropy-iers-data), or LEONAV_EOP_FILE.")
    p.add_argument("--date", metavar="ISO-UTC", help="date and time, e.g. 2026-02-23T12:00:00Z (default: now)")
    p.add_argument("--days", type=int, default=1, metavar="N", help="also show the next N-1 days (default 1)")
    p.add_argument("--json", action="store_true", help="print JSON instead of the table")
    p.set_defaults(func=_run)
