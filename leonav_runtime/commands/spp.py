"""`leonav spp`: single-point positioning of RINEX / u-blox observations, RTKLIB .pos and CSV.

    leonav spp OBS [OBS...] --nav NAV [NAV...] [--elevation-mask DEG] [--cn0-mask DBHZ]
               [--iono klobuchar|off] [--tropo saastamoinen|off] [--systems GECJ] [--no-raim]
               [--residuals] [--ekf [--q-acc Q]] [--compare REF.pos ...] [--out DIR]

Per OBS file: `<name>.pos` (RTKLIB's format), `<name>.csv` (per epoch: time, latitude,
longitude, height, ECEF, clock, inter-system biases, satellites, DOPs, sigmas, chi-square,
status), with --residuals `<name>_satellites.csv` (per satellite and epoch: elevation, azimuth,
atmosphere terms, residual, sigma, status), with --ekf `<name>_ekf.pos` / `<name>_ekf.csv` (GNSS-only
EKF with the constant-velocity model), and `spp.json` (options, counts of rejected rows by
reason, per-file figures). Equations: docs/gnss.md.
"""
from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.common.output import add_out_argument, results_dir, write_csv, write_json


def _is_rinex(path: Path) -> bool:
    """RINEX (plain or compressed) rather than a u-blox log."""
    from leonav_runtime.gnss.rinex_files import looks_like_rinex

    return looks_like_rinex(path)


def _load_navs(paths: list[str], cache: dict | None = None):
    """(ephemerides, Klobuchar coefficients or None) of RINEX navigation files; with `cache`
    (one dict per run) read once for every OBS file of the run."""
    from leonav_runtime.gnss.signals import load_nav_files

    key = tuple(str(p) for p in paths)
    if cache is None:
        return load_nav_files(paths)
    if key not in cache:
        cache[key] = load_nav_files(paths)
    return cache[key]


def _check(args) -> None:
    if not 0.0 <= args.elevation_mask <= 90.0 or not math.isfinite(args.elevation_mask):
        raise UserInputError(f"--elevation-mask {args.elevation_mask}: expected degrees in 0..90")
    if not 0.0 <= args.cn0_mask < 100.0 or not math.isfinite(args.cn0_mask):
        raise UserInputError(f"--cn0-mask {args.cn0_mask}: expected dB-Hz in 0..100")
    bad = set(args.systems.upper()) - set("GECJ")
    if bad or not args.systems:
        raise UserInputError(f"--systems {args.systems!r}: expected letters of G (GPS), E (Galileo), C (BeiDou), "
                             "J (QZSS)")
    if args.compare and len(args.compare) != len(args.obs):
        raise UserInputError(f"--compare: {len(args.compare)} reference file(s) for {len(args.obs)} OBS file(s); "
                             "give one .pos per OBS file, in the same order")
    if not args.q_acc >= 0.0:
        raise UserInputError(f"--q-acc {args.q_acc}: expected a PSD >= 0 (m^2/s^3)")


def process(obs_path: Path, nav_paths: list[str], args, nav_funcs, out: Path, reference: str | None = None,
            nav_cache: dict | None = None) -> dict:
    """Solve one observation file and write its outputs; returns its summary. nav_cache: a
    dict shared by the files of one run, so that the --nav files are read once."""
    from leonav_runtime.gnss import solution_io, spp   # gnss_ekf (and the filter it imports) only for --ekf
    from leonav_runtime.gnss.rinex_obs import read_rinex_obs
    from leonav_runtime.gnss.signals import REASONS, SYSTEM_NAMES, gnss_rows

    t_start = time.perf_counter()
    if _is_rinex(obs_path):
        if not nav_paths:
            raise UserInputError(f"{obs_path}: a RINEX observation file needs --nav NAV (broadcast ephemerides)")
        obs = read_rinex_obs(obs_path)
        eph, klob = _load_navs(nav_paths, nav_cache)
        inputs = [str(obs_path)] + [str(p) for p in nav_paths]
    else:
        from leonav_runtime.gnss.signals import klobuchar_coefficients
        from leonav_runtime.gnss.ubx_log import read_ubx_log

        log = read_ubx_log(obs_path)
        obs, eph, klob = log.observations, log.ephemerides, klobuchar_coefficients(log.iono)
        if nav_paths:
            eph2, klob2 = _load_navs(nav_paths, nav_cache)
            eph, klob = eph.concat(eph2).deduplicate(), klob2 if klob2 is not None else klob
        inputs = [str(obs_path)] + [str(p) for p in nav_paths]
    if len(obs) == 0:
        raise UserInputError(f"{obs_path}: no observations could be read")
    if len(eph) == 0:
        raise UserInputError(f"{obs_path}: no broadcast ephemeris (give --nav, or a u-blox log with RXM-SFRBX)")
    t_read = time.perf_counter()
    rows = gnss_rows(obs, eph, klobuchar=klob, iono=args.iono == "klobuchar", tropo=args.tropo == "saastamoinen",
                     systems=args.systems.upper(), cn0_mask_dbhz=args.cn0_mask)
    if rows.counts.get("usable", 0) == 0:
        reasons = {k: v for k, v in rows.counts.items() if k in REASONS.values() and v}
        raise UserInputError(f"{obs_path}: no usable pseudorange (rows by reason: {reasons})")
    opts = spp.SppOptions(elevation_mask_deg=args.elevation_mask, raim=not args.no_raim)
    res = spp.solve(rows, opts, approx_ecef_m=obs.approx_position_ecef_m, nav=nav_funcs)
    t_solve = time.perf_counter()

    stem = obs_path.name.replace(".", "_") if obs_path.suffix else obs_path.name
    systems = sorted({s for s in rows.system[rows.status == 0]})
    options = {"pos mode": "Single", "elev mask": f"{args.elevation_mask:.1f} deg",
               "snr mask": f"{args.cn0_mask:.1f} dBHz" if args.cn0_mask > 0 else "off",
               "ionos opt": "Broadcast (Klobuchar)" if rows.iono_on else "OFF",
               "tropo opt": "Saastamoinen" if rows.tropo_on else "OFF", "ephemeris": "Broadcast",
               "navi sys": " ".join(SYSTEM_NAMES[s] for s in systems), "raim": "on" if opts.raim else "off"}
    ok = res.solved
    solution_io.write_pos(out / f"{stem}.pos", res.t_gps_s[ok], res.r_ecef_m[ok], res.cov_enu_m2[ok], res.ns[ok],
                          res.clock_m[ok], inputs=inputs, options=options)
    _write_epochs_csv(out / f"{stem}.csv", res)
    if args.residuals:
        _write_satellites_csv(out / f"{stem}_satellites.csv", res)
    from leonav_runtime.gnss.spp import EPOCH_STATUS
    summary = {
        "obs": str(obs_path), "nav": [str(p) for p in nav_paths], "epochs": int(res.t_gps_s.size),
        "epochs_solved": int(ok.sum()), "epochs_by_status": {EPOCH_STATUS[k]: int((res.status == k).sum())
                                                              for k in EPOCH_STATUS},
        "rows_by_reason": {k: int(v) for k, v in sorted(res.counts.items()) if not k.startswith("epochs_")},
        "reader_counts": {k: int(v) for k, v in sorted(obs.counts.items())},
        "reader_rejections": [str(r) for r in obs.rejected[:50]],
        "ephemeris_rejections": [str(r) for r in eph.rejected[:50]],
        "klobuchar": None if klob is None else [float(v) for v in klob],
        "scatter_rms_3d_m": _scatter(res.r_ecef_m[ok]),
        "mean_position_ecef_m": res.r_ecef_m[ok].mean(axis=0).tolist() if ok.any() else None,
        "median_ns": float(np.median(res.ns[ok])) if ok.any() else None,
        "times_s": {"read": t_read - t_start, "solve": t_solve - t_read},
    }
    if args.ekf:
        if not ok.any():   # the EKF starts from a single-point solution; say why there is none
            raise UserInputError(f"{obs_path}: --ekf: no epoch has a single-point solution to start the "
                                 f"GNSS-only EKF from ({_why_unsolved(summary)})")
        from leonav_runtime.gnss import gnss_ekf

        sol = gnss_ekf.run(res, q_acc_m2ps3=args.q_acc, nav=nav_funcs)
        have = np.all(np.isfinite(sol.r_ecef_m), axis=1)
        solution_io.write_pos(out / f"{stem}_ekf.pos", sol.t_gps_s[have], sol.r_ecef_m[have], _enu_cov(sol, have),
                              sol.ns[have], sol.clock_m[have], inputs=inputs,
                              options={**options, "pos mode": "GNSS-only EKF, constant velocity",
                                       "q_acc": f"{args.q_acc:g} m^2/s^3"}, program="leonav spp --ekf")
        _write_ekf_csv(out / f"{stem}_ekf.csv", sol)
        summary["ekf"] = {"scatter_rms_3d_m": gnss_ekf.scatter_rms_m(sol.r_ecef_m),
                          "applied": sol.run.n_applied, "gated": sol.run.n_gated, "failed": sol.run.n_failed,
                          "q_acc_m2ps3": args.q_acc}
    if reference:
        summary["compare"] = {str(reference): solution_io.compare_pos(solution_io.read_pos(out / f"{stem}.pos"),
                                                                       solution_io.read_pos(reference))}
    summary["times_s"]["total"] = time.perf_counter() - t_start
    return summary


def _why_unsolved(summary: dict) -> str:
    """'epochs by status: ...; rows not used: ...' of a file summary (non-zero counts only)."""
    epochs = ", ".join(f"{k} {v}" for k, v in summary["epochs_by_status"].items() if v)
    rows = ", ".join(f"{k} {v}" for k, v in summary["rows_by_reason"].items()
                     if k not in ("usable", "used", "other_signal", "system_not_used") and v)
    return f"epochs by status: {epochs or 'none'}; rows not used: {rows or 'none'}"


def _reader_note(counts: dict) -> str:
    """The epoch-order repairs of the RINEX reader, for the printed summary ('' when none)."""
    parts = []
    if counts.get("epochs_out_of_order"):
        n = counts["epochs_out_of_order"]
        parts.append(f"{n} epoch{'s' if n > 1 else ''} out of time order (sorted)")
    if counts.get("duplicate_epochs"):
        n = counts["duplicate_epochs"]
        parts.append(f"{n} repeated epoch{'s' if n > 1 else ''} (dropped)")
    return ", ".join(parts)


def _enu_cov(sol, have):
    return sol.cov_enu_m2[have]


def _scatter(r: np.ndarray) -> float | None:
    if not len(r):
        return None
    return float(np.sqrt(np.mean(np.sum((r - r.mean(axis=0)) ** 2, axis=1))))


def _write_epochs_csv(path: Path, res) -> None:
    from leonav_runtime.gnss import time as gtime
    from leonav_runtime.gnss.spp import EPOCH_STATUS

    header = ["t_gps_s", "week", "tow_s", "lat_deg", "lon_deg", "height_m", "x_ecef_m", "y_ecef_m", "z_ecef_m",
              "clock_m", "isb_gal_m", "isb_bds_m", "ns", "gdop", "pdop", "hdop", "vdop", "sdn_m", "sde_m", "sdu_m",
              "chi2", "dof", "n_excluded", "status", "satellites"]
    rows = []
    weeks, tows = gtime.week_tow(res.t_gps_s)
    lat_deg, lon_deg = np.degrees(res.lat_rad), np.degrees(res.lon_rad)
    for e in range(res.t_gps_s.size):
        week, tow = weeks[e], tows[e]
        c = res.cov_enu_m2[e]
        sd = [math.sqrt(c[1, 1]), math.sqrt(c[0, 0]), math.sqrt(c[2, 2])] if np.all(np.isfinite(c)) else [math.nan] * 3
        rows.append([f"{res.t_gps_s[e]:.3f}", int(week), f"{float(tow):.3f}", f"{lat_deg[e]:.9f}",
                     f"{lon_deg[e]:.9f}", f"{res.height_m[e]:.4f}",
                     *(f"{v:.4f}" for v in res.r_ecef_m[e]), f"{res.clock_m[e]:.4f}",
                     *(f"{v:.4f}" for v in res.isb_m[e]), int(res.ns[e]), *(f"{v:.3f}" for v in res.dop[e]),
                     *(f"{v:.4f}" for v in sd), f"{res.chi2[e]:.3f}", int(res.dof[e]), int(res.n_excluded[e]),
                     EPOCH_STATUS[int(res.status[e])], " ".join(res.used_sats(e))])
    write_csv(path, header, rows)


def _write_satellites_csv(path: Path, res) -> None:
    from leonav_runtime.gnss.signals import REASONS

    r = res.rows
    header = ["t_gps_s", "sat", "signal", "pseudorange_m", "cn0_dbhz", "el_deg", "az_deg", "iono_m", "tropo_m",
              "residual_m", "sigma_m", "status"]
    sats = r.sat
    rows = [[f"{r.t_gps_s[i]:.3f}", sats[i], r.signal[i], f"{r.pseudorange_m[i]:.3f}", f"{r.cn0_dbhz[i]:.1f}",
             f"{math.degrees(res.el_rad[i]):.3f}", f"{math.degrees(res.az_rad[i]) % 360.0:.3f}",
             f"{res.iono_m[i]:.4f}", f"{res.tropo_m[i]:.4f}", f"{res.residual_m[i]:.4f}", f"{res.sigma_m[i]:.4f}",
             "used" if res.row_status[i] == 0 else REASONS.get(int(res.row_status[i]), str(res.row_status[i]))]
            for i in range(len(r))]
    write_csv(path, header, rows)


def _write_ekf_csv(path: Path, sol) -> None:
    from leonav_runtime.orbits import geometry

    header = ["t_gps_s", "lat_deg", "lon_deg", "height_m", "x_ecef_m", "y_ecef_m", "z_ecef_m", "ve_mps", "vn_mps",
              "vu_mps", "clock_m", "sde_m", "sdn_m", "sdu_m", "n_applied", "n_gated"]
    lat, lon, h = geometry.ecef_to_geodetic(np.nan_to_num(sol.r_ecef_m, nan=6.4e6))
    rows = []
    for e in range(sol.t_gps_s.size):
        if not np.all(np.isfinite(sol.r_ecef_m[e])):
            continue
        sd = np.sqrt(np.diag(sol.cov_enu_m2[e]))
        rows.append([f"{sol.t_gps_s[e]:.3f}", f"{math.degrees(lat[e]):.9f}", f"{math.degrees(lon[e]):.9f}",
                     f"{h[e]:.4f}", *(f"{v:.4f}" for v in sol.r_ecef_m[e]), *(f"{v:.4f}" for v in sol.v_enu_mps[e]),
                     f"{sol.clock_m[e]:.4f}", *(f"{v:.4f}" for v in sd), int(sol.ns[e]), int(sol.gated[e])])
    write_csv(path, header, rows)


def _run(args: argparse.Namespace) -> int:
    from leonav_runtime.core.navfuncs import NavFunctions

    _check(args)
    t0 = time.perf_counter()
    out = results_dir(args.out, "spp")
    nav_funcs = NavFunctions()
    refs = args.compare or [None] * len(args.obs)
    nav_cache: dict = {}
    summaries = [process(Path(p), args.nav, args, nav_funcs, out, ref, nav_cache) for p, ref in zip(args.obs, refs)]
    from leonav_runtime.common.provenance import provenance

    write_json(out / "spp.json", {"provenance": provenance(),
                                  "options": {k: v for k, v in vars(args).items() if k != "func"},
                                  "files": summaries, "total_s": time.perf_counter() - t0})
    for s in summaries:
        reasons = ", ".join(f"{k} {v}" for k, v in s["rows_by_reason"].items()
                            if k not in ("usable", "used", "other_signal", "system_not_used") and v)
        line = (f"{s['obs']}: {s['epochs_solved']}/{s['epochs']} epochs solved, median {s['median_ns']} satellites, "
                f"scatter {s['scatter_rms_3d_m'] or math.nan:.2f} m (3-D RMS about the mean)")
        if "ekf" in s:
            line += f"; EKF scatter {s['ekf']['scatter_rms_3d_m']:.2f} m"
        print(line)
        print(f"  rows not used: {reasons or 'none'}")
        if _reader_note(s["reader_counts"]):
            print(f"  reader: {_reader_note(s['reader_counts'])}")
        for ref, c in s.get("compare", {}).items():
            print(f"  vs {ref}: {c['epochs_matched']} epochs, 3-D difference median {c['median_3d_m']:.4f} m, "
                  f"max {c['max_3d_m']:.4f} m, same satellite count {c['same_ns']}/{c['epochs_matched']}")
    print(f"results: {out}/")
    return 0


def register(subparsers) -> None:
    """Add the `spp` subcommand."""
    p = subparsers.add_parser(
        "spp", help="single-point positioning of RINEX / u-blox observations (RTKLIB .pos and CSV)",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("obs", nargs="+", metavar="OBS", help="RINEX 2/3 observation file(s) or u-blox log(s)")
    p.add_argument("--nav", nargs="+", default=[], metavar="NAV",
                   help="RINEX navigation file(s) (GPS/Galileo/BeiDou/QZSS); merged")
    p.add_argument("--elevation-mask", type=float, default=10.0, metavar="DEG",
                   help="satellites below this elevation are not used, deg (default 10)")
    p.add_argument("--cn0-mask", type=float, default=0.0, metavar="DBHZ",
                   help="signals with a C/N0 below this are not used, dB-Hz (default 0: off; rows without C/N0 pass)")
    p.add_argument("--iono", choices=("klobuchar", "off"), default="klobuchar",
                   help="ionosphere: GPS broadcast Klobuchar model (default) or none (rnx2rtkp -p 0's default)")
    p.add_argument("--tropo", choices=("saastamoinen", "off"), default="saastamoinen",
                   help="troposphere: Saastamoinen, standard atmosphere, 1/sin(el) (default) or none")
    p.add_argument("--systems", default="GECJ", metavar="LETTERS",
                   help="constellations to use: G GPS, E Galileo, C BeiDou, J QZSS (default GECJ)")
    p.add_argument("--no-raim", action="store_true",
                   help="no exclusion: an epoch failing the chi-square test gets no solution (as rnx2rtkp)")
    p.add_argument("--residuals", action="store_true",
                   help="also write <name>_satellites.csv: elevation, azimuth, atmosphere terms, residual, sigma "
                        "and status of every satellite at every epoch")
    p.add_argument("--ekf", action="store_true",
                   help="also run the GNSS-only EKF (constant-velocity model, no IMU)")
    p.add_argument("--q-acc", type=float, default=1e-10, metavar="M2PS3",
                   help="EKF white-acceleration PSD, m^2/s^3 (default 1e-10: static receiver; a car ~1)")
    p.add_argument("--compare", nargs="+", default=[], metavar="POS",
                   help="one reference .pos file per OBS file, same order (e.g. from rnx2rtkp): print the 3-D "
                        "differences and how often the satellite counts agree")
    add_out_argument(p)
    p.set_defaults(func=_run)


def main(argv: list[str] | None = None) -> int:
    """`python -m leonav_runtime.commands.spp ...`: the same command without loading the other
    `leonav` subcommands (some import SciPy and the simulator): a lean entry for scripts."""
    import sys

    from leonav_runtime.common.errors import UserInputError as _UIE

    from leonav_runtime.common.arg_parser import OneLineErrorParser

    parser = OneLineErrorParser(prog="leonav")
    register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["spp", *(sys.argv[1:] if argv is None else argv)])
    try:
        return int(args.func(args) or 0)
    except _UIE as exc:
        print(f"leonav spp: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
