"""`leonav replay SESSION`: a recorded session through the filter in fix+imu, leo-alpha+imu, fix+leo-alpha+imu,
and (asked for with --modes) the tightly coupled pseudorange+imu and pseudorange+leo-alpha+imu."""
from __future__ import annotations

import argparse
import math

from leonav_runtime.common import output
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.replay.options import parse_latency


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "replay",
        help="replay a `leonav record` session through the filter (fix+imu, leo-alpha+imu, fix+leo-alpha+imu)",
        description=(
            "Decode a session folder (gnss.raw, imu.raw with their chunk stamps, sdr.cu8 + sdr.sigmf-meta), put "
            "every record on one time axis (host monotonic stamps -> UTC through the GNSS time map), build the IMU, "
            "GNSS fix (NMEA/UBX position fixes) and Doppler-rate (beacon pipeline on the capture) tables, turn them "
            "into filter inputs (leonav_runtime.inputs) and run the generated filter per mode: fix+imu (position "
            "fixes; the old name gps+imu is accepted), leo-alpha+imu, fix+leo-alpha+imu, and on request the tightly "
            "coupled pseudorange+imu and pseudorange+leo-alpha+imu (the receiver's RXM-RAWX pseudoranges and Doppler "
            "with ephemerides from its RXM-SFRBX or --nav; a session without position fixes starts from and is "
            "scored against the single-point solutions). Writes metrics.json, "
            "rmse_vs_time.csv/.png, trajectory.csv, trajectories.png and the beacon outputs (beacons/). "
            "Reference: truth.csv if the session has one (synthetic sessions), else the GNSS fixes."),
    )
    p.add_argument("session", metavar="SESSION", help="session folder written by `leonav record` (or `leonav session synth`)")
    p.add_argument("--tle", action="append", default=[], metavar="FILE",
                   help="Starlink element sets (TLE/3LE/OMM) of the session's day, repeatable (default: the built-in "
                        "Walker constellation, only right for synthetic sessions)")
    p.add_argument("--corrections", default=None, metavar="FILE",
                   help="a base's differential corrections as recorded by `leonav base --record FILE`, applied to "
                        "the Doppler-rate (docs/corrections.md)")
    p.add_argument("--corrections-max-age", type=float, default=None, metavar="S",
                   help="oldest correction used (s, default 10)")
    p.add_argument("--operator-ephemerides", default=None, metavar="DIR",
                   help="folder of Starlink operator ephemerides (MANIFEST.txt and MEME_*.txt): satellites with a "
                        "file over their measurement times take their states from it instead of their element "
                        "sets, joined by name (docs/ephemerides.md)")
    p.add_argument("--orbit-states", default=None, metavar="R,A,C",
                   help="estimate each Starlink satellite's radial, along-track and cross-track orbit offset as "
                        "states, with these prior sigmas in m (ephemeris method 1; e.g. 240,960,170 for element "
                        "sets 6 h old); reported per satellite in metrics.json")
    p.add_argument("--modes", default=",".join(_modes()[0]), metavar="LIST",
                   help=f"comma-separated modes of {', '.join(_modes()[1])} (default %(default)s)")
    p.add_argument("--nav", action="append", default=[], metavar="RINEX_NAV",
                   help="RINEX navigation file(s) for the pseudorange modes, repeatable (besides the RXM-SFRBX "
                        "ephemerides in gnss.raw)")
    p.add_argument("--elevation-mask", type=float, default=10.0, metavar="DEG",
                   help="pseudorange modes: elevation mask, deg (default %(default)g)")
    p.add_argument("--origin", nargs=3, type=float, default=None, metavar=("LAT", "LON", "H"),
                   help="ENU origin and site: deg, deg, m above the ellipsoid (default: the first GNSS fix)")
    p.add_argument("--yaw-deg", type=float, default=None, metavar="DEG",
                   help="initial heading, deg from East towards North (default: the WitMotion yaw output)")
    p.add_argument("--gnss-latency", default="0", metavar="S|estimate",
                   help="receiver output latency to remove from the time map, s (measure it with a PPS; default 0), "
                   "or 'estimate': a filter state (fix latency dt_fix, prior 0 +- 0.3 s), reported per mode")
    p.add_argument("--doppler-rate-sigma-floor", "--alpha-sigma-floor", dest="doppler_rate_sigma_floor", type=float,
                   default=0.5, metavar="HZ/S", help="lower bound of the Doppler-rate 1-sigma, Hz/s (default %(default)g)")
    from leonav_runtime.commands.run import add_reference_arguments

    add_reference_arguments(p, heights=False)
    p.add_argument("--no-truth", action="store_true", help="ignore truth.csv; score against the GNSS fixes")
    output.add_out_argument(p)
    p.set_defaults(func=run)


def _modes():
    from leonav_runtime.replay.options import ALL_MODES, MODES

    return MODES, ALL_MODES


def _sigmas(text: str | None) -> tuple[float, ...] | None:
    """--orbit-states R,A,C -> three floats (checked by the replay options)."""
    if text is None:
        return None
    try:
        return tuple(float(v) for v in text.split(","))
    except ValueError:
        raise UserInputError(f"--orbit-states: {text!r}: expected three sigmas in m, e.g. 240,960,170") from None


def _fmt(v, scale=1.0, digits=2) -> str:
    return "-" if v is None else f"{v * scale:.{digits}f}"


def run(args: argparse.Namespace) -> int:
    from leonav_runtime.common.progress import progress as make_progress

    from leonav_runtime import replay
    from leonav_runtime.commands.run import reference_options

    modes = tuple(m.strip() for m in args.modes.split(",") if m.strip())   # old names: a note in the metrics
    if not (math.isfinite(args.doppler_rate_sigma_floor) and args.doppler_rate_sigma_floor >= 0):
        raise UserInputError(f"--doppler-rate-sigma-floor: {args.doppler_rate_sigma_floor!r}: expected a number "
                             ">= 0 (Hz/s)")
    if args.yaw_deg is not None and not math.isfinite(args.yaw_deg):
        raise UserInputError("--yaw-deg: expected a finite angle in degrees")
    options = replay.ReplayOptions(modes=modes, origin_deg=tuple(args.origin) if args.origin else None,
                                   yaw_deg=args.yaw_deg, doppler_rate_sigma_floor_hz_s=args.doppler_rate_sigma_floor,
                                   use_truth=not args.no_truth, gnss_latency_s=parse_latency(str(args.gnss_latency)),
                                   nav_paths=tuple(args.nav), elevation_mask_deg=args.elevation_mask,
                                   reference_file=reference_options(args),
                                   operator_ephemerides=args.operator_ephemerides, corrections=args.corrections,
                                   corrections_max_age_s=args.corrections_max_age,
                                   orbit_states_sigma_m=_sigmas(args.orbit_states))
    if args.origin:
        lat, lon, h = args.origin
        if not (abs(lat) <= 90 and abs(lon) <= 360 and -11_000 <= h <= 1e5):
            raise UserInputError(f"--origin: {args.origin}: expected LAT in [-90, 90] deg, LON deg, H in m")
    from leonav_runtime.orbits.elements import load_element_files

    elements = load_element_files(args.tle)
    out = output.results_dir(args.out, "replay")
    with make_progress(None, "beacon capture", "S", unit_scale=True, leave=False) as bar:
        metrics = replay.replay_session(args.session, out, options, elements=elements, progress=bar.update)
    print(f"replay {args.session} -> {out}  (reference: {metrics['reference'] or 'none'})")
    b = metrics["beacons"].get("counts")
    if b:
        print(f"  beacons: {b['ridges']} ridges, {b['associated']} associated, {b['ambiguous']} ambiguous, "
              f"{b['unassociated']} unassociated; {metrics['counts'].get('doppler_rate_records', 0)} "
              "Doppler-rate records")
    elif metrics["beacons"].get("reason_empty"):
        print(f"  beacons: none ({metrics['beacons']['reason_empty']})")
    if b:
        print(f"  carrier f_c: {metrics['f_c_hz'] / 1e9:.6f} GHz, {metrics['f_c_source']}")
    print(f"  {'mode':<20} {'pos RMSE m':>10} {'vel m/s':>8} {'att deg':>8} {'applied':>8} {'gated':>6} {'failed':>6}")
    for mode, m in metrics["modes"].items():
        r = m["records"]
        print(f"  {mode:<20} {_fmt(m['rmse_position_m']):>10} {_fmt(m['rmse_velocity_mps']):>8} "
              f"{_fmt(m['rmse_attitude_deg']):>8} {r['applied']:>8} {r['gated']:>6} {r['failed']:>6}")
    rf = metrics.get("reference_file")
    if rf:
        print(f"  against {rf['path']} ({rf['epochs']} epochs): horizontal / vertical RMSE m: " + ", ".join(
            f"{mode} {_fmt(s['rmse_horizontal_m'], digits=3)} / {_fmt(s['rmse_vertical_m'], digits=3)}"
            for mode, s in rf["modes"].items()))
    for mode, reason in metrics["skipped_modes"].items():
        print(f"  {mode:<20} skipped: {reason}")
    for note in metrics["notes"]:
        print(f"  note: {note}")
    if not metrics["modes"]:
        reasons = "; ".join(f"{mode}: {reason}" for mode, reason in metrics["skipped_modes"].items())
        raise UserInputError(f"{args.session}: no mode could run ({reasons or 'none asked'})")
    return 0
