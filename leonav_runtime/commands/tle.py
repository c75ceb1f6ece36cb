"""`leonav tle`: fetch element sets from CelesTrak, inspect an element file, write built-ins.

    leonav tle fetch GROUP [--format json|xml|tle] [--cache DIR] [--url-base URL] [--timeout S] [--max-mb MB] [--force]
    leonav tle info FILE [--epoch ISO-UTC] [--stale-days D] [--out DIR]
    leonav tle builtin {starlink,gps} [--epoch ISO-UTC] [--out DIR]
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
from pathlib import Path

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.common.utc import parse_utc
from leonav_runtime.common.output import add_out_argument, results_dir, write_json


def _parse_epoch(text: str | None) -> _dt.datetime:
    if text is None:
        return _dt.datetime.now(_dt.timezone.utc)
    try:
        return parse_utc(text, "--epoch", require_zone=True)
    except OverflowError:  # e.g. year 1 with a positive UTC offset
        raise UserInputError(f"--epoch: {text!r} is out of the representable range; "
                             "expected e.g. 2026-02-23T12:00:00Z") from None


def _cmd_fetch(args: argparse.Namespace) -> int:
    import math

    from leonav_runtime.orbits.fetch import fetch_group

    if not (math.isfinite(args.max_mb) and args.max_mb > 0):
        raise UserInputError(f"--max-mb: {args.max_mb!r}: expected a positive number of megabytes")
    from leonav_runtime.orbits.fetch import sidecar_path

    path = fetch_group(args.group, cache_dir=args.cache, url_base=args.url_base, timeout_s=args.timeout,
                       max_bytes=max(1, int(args.max_mb * 1e6)), force=args.force, fmt=args.format)
    meta = json.loads(sidecar_path(path).read_text())
    print(f"{meta['count']} element sets of group {meta['group']!r} ({args.format.upper()}) -> {path} "
          f"(epochs {meta['epoch_min_utc']} .. {meta['epoch_max_utc']}, {meta['rejected']} rejected)")
    for problem in meta.get("problems") or []:
        print(f"  accepted with --force despite: {problem}")
    return 0


def element_info(path: str | Path, epoch_utc: _dt.datetime, stale_after_days: float) -> dict:
    """Summary of an element file: count, epoch range, ages at `epoch_utc`, rejected entries."""
    import warnings

    from leonav_runtime.orbits import load_elements

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the rejections are reported in the summary instead
        elements = load_elements(path, stale_after_days=stale_after_days)
    ages_d = elements.ages_s(epoch_utc) / 86400.0
    epochs = sorted(elements.epochs_utc)
    return {
        "file": str(path),
        "count": len(elements),
        "constellation": elements.constellation,
        "epoch_min_utc": epochs[0],
        "epoch_max_utc": epochs[-1],
        "reference_epoch_utc": epoch_utc,
        "age_days": {"min": float(ages_d.min()), "median": float(np.median(ages_d)), "max": float(ages_d.max())},
        "stale_after_days": stale_after_days,
        "stale_count": int(np.sum(np.abs(ages_d) > stale_after_days)),
        "rejected_count": len(elements.rejected),
        "rejected": [{"line": r.line, "name": r.name, "reason": r.reason} for r in elements.rejected],
    }


def _cmd_info(args: argparse.Namespace) -> int:
    import math

    if not (math.isfinite(args.stale_days) and args.stale_days >= 0):
        raise UserInputError(f"--stale-days: {args.stale_days!r}; expected a number of days >= 0")
    epoch = _parse_epoch(args.epoch)
    info = element_info(args.file, epoch, args.stale_days)
    path = write_json(results_dir(args.out, "tle-info") / "tle_info.json", info) if args.out else None
    age = info["age_days"]
    print(f"{info['file']}: {info['count']} {info['constellation']} element sets, epochs "
          f"{info['epoch_min_utc'].isoformat()} .. {info['epoch_max_utc'].isoformat()}")
    print(f"  age at {epoch.isoformat()}: min {age['min']:.2f} d, median {age['median']:.2f} d, "
          f"max {age['max']:.2f} d; {info['stale_count']} older than {args.stale_days:g} d")
    print(f"  rejected: {info['rejected_count']}")
    for rej in info["rejected"][:10]:
        print(f"    line {rej['line']}: {rej['reason']}")
    if path is not None:
        print(f"  -> {path}")
    return 0


def _cmd_builtin(args: argparse.Namespace) -> int:
    from leonav_runtime.orbits import gps_walker_tle, starlink_walker_tle

    epoch = _parse_epoch(args.epoch)
    text = (starlink_walker_tle if args.constellation == "starlink" else gps_walker_tle)(epoch)
    out = results_dir(args.out, "tle-builtin")
    path = out / f"{args.constellation}_walker.tle"
    path.write_text(text)
    count = sum(1 for line in text.splitlines() if line.startswith("1 "))
    print(f"{count} generated {args.constellation} element sets at {epoch.isoformat()} -> {path}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add `leonav tle` with its fetch / info / builtin actions."""
    parser = subparsers.add_parser("tle", help="fetch, inspect or generate satellite element sets (TLE/OMM)",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    actions = parser.add_subparsers(dest="tle_action", metavar="ACTION")
    parser.set_defaults(func=lambda args: (parser.print_help(), 2)[1])

    fetch = actions.add_parser("fetch", help="download a CelesTrak group into the cache")
    fetch.add_argument("group", metavar="GROUP",
                       help="group: starlink, gps (CelesTrak's gps-ops, also accepted) or another CelesTrak group")
    fetch.add_argument("--format", choices=("json", "xml", "tle"), default="json",
                       help="json (default) or xml: CCSDS OMM, no 5-digit catalogue-number limit; tle: "
                            "TLE text (runs out of catalogue numbers). Cached as <group>.omm.json / .omm.xml / .tle")
    fetch.add_argument("--cache", metavar="DIR", default=None,
                       help="cache folder (default $XDG_CACHE_HOME/leonav/tle or ~/.cache/leonav/tle)")
    fetch.add_argument("--url-base", metavar="URL", default=None,
                       help="GP query URL (default https://celestrak.org/NORAD/elements/gp.php)")
    fetch.add_argument("--timeout", metavar="S", type=float, default=60.0,
                       help="deadline of the whole download (connect, redirects, reading), s (default 60)")
    fetch.add_argument("--max-mb", metavar="MB", type=float, default=64.0,
                       help="largest reply accepted, MB (default 64; CelesTrak's groups are a few MB)")
    fetch.add_argument("--force", action="store_true",
                       help="replace the cache even when the reply has rejected entries or fewer than 90%% of "
                            "the cached group's element sets (by default such a reply is refused as a likely "
                            "truncated download)")
    fetch.set_defaults(func=_cmd_fetch)

    info = actions.add_parser("info", help="count, epoch range, ages and rejected entries of an element file")
    info.add_argument("file", metavar="FILE", help="TLE / 3LE / OMM (XML, JSON, CSV) file")
    info.add_argument("--epoch", metavar="ISO", default=None,
                      help="reference UTC time for ages (default: now), e.g. 2026-02-23T12:00:00Z")
    info.add_argument("--stale-days", metavar="D", type=float, default=3.0,
                      help="age beyond which elements count as stale, days (default 3)")
    info.add_argument("--out", metavar="DIR", default=None,
                      help="also write tle_info.json into DIR (default: print only, no files written)")
    info.set_defaults(func=_cmd_info)

    builtin = actions.add_parser("builtin", help="write a generated Walker constellation as 3LE text")
    builtin.add_argument("constellation", choices=("starlink", "gps"),
                         help="which generated Walker constellation: starlink (9,616 satellites in shells) or gps (31, planes A-F)")
    builtin.add_argument("--epoch", metavar="ISO", default=None, help="element epoch, UTC (default: now)")
    add_out_argument(builtin)
    builtin.set_defaults(func=_cmd_builtin)
