"""`leonav sky`: visible GPS/Starlink satellites from a site, as counts, JSON and a sky plot."""
from __future__ import annotations

import argparse
import datetime as _dt
import math
import warnings
from pathlib import Path

import numpy as np

from leonav_runtime.common import output
from leonav_runtime.orbits import geometry
from leonav_runtime.sky import view as sky, plot as sky_plot
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.common.utc import parse_utc

DEFAULT_DURATION_S = 600.0
DEFAULT_STEP_S = 10.0


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "sky",
        help="visible GPS/Starlink satellites from a site: counts, DOP, sky plot",
        description=(
            "Propagate GPS and Starlink element sets (SGP4) over a time window and report, per "
            "constellation, how many satellites are above the elevation mask (the paper's 10 deg "
            "for GPS, 28 deg for Starlink), GPS DOP and element-set ages. Writes sky.json, "
            "visible_counts.csv and sky.png (polar tracks + visible count versus time). Without "
            "--tle it uses generated Walker constellations (GPS, ~9,600 Starlink) at the start "
            "epoch."
        ),
    )
    site = sky.ROCHESTER
    p.add_argument("--lat", type=float, default=math.degrees(site.lat_rad), metavar="DEG",
                   help="site geodetic latitude, deg (default: the paper's Rochester site %(default).7f)")
    p.add_argument("--lon", type=float, default=math.degrees(site.lon_rad), metavar="DEG",
                   help="site longitude, deg east (default %(default).7f)")
    p.add_argument("--alt", type=float, default=site.h_m, metavar="M",
                   help="site height above the WGS84 ellipsoid, m (default %(default)g)")
    p.add_argument("--start", metavar="ISO-UTC", default=None,
                   help="window start, e.g. 2026-02-23T12:00:00Z (default: now, rounded to the second, "
                        "with the built-in constellations; the newest element-set epoch in the files with --tle)")
    p.add_argument("--duration", type=float, default=DEFAULT_DURATION_S, metavar="S",
                   help="window length, s (default %(default)g: a Starlink pass above 28 deg lasts a few "
                        "minutes, so 10 minutes shows whole arcs and the turnover of the visible set; the "
                        "paper's 20 s run would show dots)")
    p.add_argument("--step", type=float, default=DEFAULT_STEP_S, metavar="S",
                   help="time step, s (default %(default)g)")
    p.add_argument("--tle", action="append", default=[], metavar="FILE",
                   help="TLE/3LE file with real element sets (repeatable); the constellation comes from the "
                        "file (starlink, gps, else unknown with a 10 deg mask)")
    p.add_argument("--mask-gps", type=float, default=math.degrees(geometry.ELEVATION_MASK_DEFAULTS_RAD["gps"]),
                   metavar="DEG", help="GPS elevation mask, deg (default %(default)g)")
    p.add_argument("--mask-starlink", type=float,
                   default=math.degrees(geometry.ELEVATION_MASK_DEFAULTS_RAD["starlink"]),
                   metavar="DEG", help="Starlink elevation mask, deg (default %(default)g)")
    output.add_out_argument(p)
    p.set_defaults(func=run)


def _round_to_second(t: _dt.datetime) -> _dt.datetime:
    return (t + _dt.timedelta(microseconds=500_000)).replace(microsecond=0)


EARLIEST_UTC = _dt.datetime(1900, 1, 1, tzinfo=_dt.timezone.utc)
LATEST_UTC = _dt.datetime(2200, 1, 1, tzinfo=_dt.timezone.utc)


def _start_time(text: str) -> _dt.datetime:
    """--start as UTC, within the years element sets can describe (so the window end exists)."""
    try:
        start = parse_utc(text, "--start", require_zone=True)
    except OverflowError:
        start = None
    if start is None or not EARLIEST_UTC <= start <= LATEST_UTC:
        raise UserInputError(f"--start: {text!r} is outside {EARLIEST_UTC.year}..{LATEST_UTC.year}; "
                             "expected a time such as 2026-02-23T12:00:00Z")
    return start


def _check_args(args) -> None:
    checks = [
        ("--lat", args.lat, -90.0, 90.0),
        ("--lon", args.lon, -180.0, 360.0),
        ("--alt", args.alt, -11_000.0, 1.0e6),
        ("--mask-gps", args.mask_gps, -90.0, 90.0),
        ("--mask-starlink", args.mask_starlink, -90.0, 90.0),
        ("--duration", args.duration, 0.0, 30 * 86400.0),
    ]
    for name, value, lo, hi in checks:
        if not (math.isfinite(value) and lo <= value <= hi):
            raise UserInputError(f"{name}: {value!r} is out of range; expected a number in [{lo:g}, {hi:g}]")
    if not (math.isfinite(args.step) and args.step > 0):
        raise UserInputError(f"--step: {args.step!r} must be a positive number of seconds")
    if args.duration / args.step > 1_000_000:
        raise UserInputError(
            f"--duration/--step: {args.duration:g} s / {args.step:g} s gives more than 1,000,000 epochs; "
            "use a larger --step"
        )
    for f in args.tle:
        if not Path(f).is_file():
            raise UserInputError(f"--tle: {f}: no such file")


def _load_files(paths: list[str]):
    from leonav_runtime.orbits import RejectedElementsWarning, group_by_constellation, load_elements

    with warnings.catch_warnings():
        # Rejected entries are reported once, in the summary and sky.json.
        warnings.simplefilter("ignore", RejectedElementsWarning)
        loaded = [load_elements(path) for path in paths]
    sources = [{"file": str(path), "constellation": (es.constellation or "unknown").lower(),
                "satellites": len(es), "rejected_entries": len(es.rejected)} for path, es in zip(paths, loaded)]
    return group_by_constellation(loaded), sources


def run(args: argparse.Namespace) -> int:
    _check_args(args)
    site = sky.Site.from_degrees(args.lat, args.lon, args.alt)
    if args.tle:
        elements, sources = _load_files(args.tle)
        if not any(len(es) for es in elements.values()):
            raise UserInputError(f"--tle: no usable element sets in {', '.join(args.tle)}")
        if args.start:
            start, start_source = _start_time(args.start), "--start"
        else:
            newest = max(max(es.epochs_utc) for es in elements.values() if len(es))
            start, start_source = _round_to_second(newest), "newest element-set epoch in the --tle files"
    else:
        from leonav_runtime.orbits import default_elements

        if args.start:
            start, start_source = _start_time(args.start), "--start"
        else:
            start, start_source = _round_to_second(_dt.datetime.now(_dt.timezone.utc)), "now"
        elements = default_elements(start)
        sources = [{"file": None, "constellation": n, "satellites": len(es),
                    "generated": "Walker constellation built at the start epoch"} for n, es in elements.items()]

    masks = {"gps": math.radians(args.mask_gps), "starlink": math.radians(args.mask_starlink)}
    t_s = np.arange(0.0, args.duration + 0.5 * args.step, args.step)
    t_s = t_s[t_s <= args.duration + 1e-9]
    view = sky.sky_view(elements, site, start, t_s, masks, show_progress=True)

    summary = sky.summarize(view)
    summary["window"]["start_source"] = start_source
    summary["elements"] = sources
    out_dir = output.results_dir(args.out, "sky")
    from leonav_runtime.common.provenance import provenance

    output.write_json(out_dir / "sky.json", {"provenance": provenance(), **summary})
    names = list(view.constellations)
    output.write_csv(
        out_dir / "visible_counts.csv",
        ["t_s", *[f"visible_{n}" for n in names]],
        ([float(t), *[int(view.constellations[n].count[k]) for n in names]] for k, t in enumerate(t_s)),
    )
    sky_plot.plot(view, out_dir / "sky.png")
    _print_summary(summary)
    print(f"wrote sky.json, visible_counts.csv, sky.png to {out_dir}")
    return 0


def _print_summary(s: dict) -> None:
    site, w = s["site"], s["window"]
    print(f"site {site['lat_deg']:.7f} deg, {site['lon_deg']:.7f} deg, {site['h_m']:g} m")
    print(f"window {w['start_utc']} + {w['duration_s']:g} s, step {w['step_s']:g} s, "
          f"{w['n_epochs']} epochs (start: {w['start_source']})")
    print(f"{'constellation':<14}{'mask':>6}{'sats':>7}{'now':>6}{'min':>6}{'mean':>7}{'max':>6}{'age d (median)':>16}")
    for name, v in s["visible"].items():
        age = s["element_age_days"][name]["median"]
        age_txt = f"{age:.2f}" if age is not None else "-"
        print(f"{name:<14}{s['masks_deg'][name]:>5g}°{s['satellites'][name]['loaded']:>7}{v['current']:>6}"
              f"{v['min']:>6}{v['mean']:>7.1f}{v['max']:>6}{age_txt:>16}")
    if "dop_gps" in s:
        d = s["dop_gps"]
        if d["pdop"]["median"] is not None:
            print("GPS DOP (min/median/max): " + ", ".join(
                f"{k.upper()} {d[k]['min']:.2f}/{d[k]['median']:.2f}/{d[k]['max']:.2f}" for k in ("pdop", "hdop", "vdop")))
        if d["reason"]:
            print(f"GPS DOP not available: {d['reason']}")
    import logging

    for warning in s["warnings"]:   # `leonav sky: warning: ...` on stderr, silenced by -q
        logging.getLogger("leonav.sky").warning(warning)
