"""`leonav beacons`: Starlink beacon IQ capture -> ridges -> Doppler-rate -> satellite IDs."""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import math
import shutil
import warnings
from pathlib import Path

from leonav_runtime.common import output
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gen.constants import STARLINK_BEACON_HZ, STARLINK_MASK_DEG

ROCHESTER_DEG = (43.0848638, -77.6786127, 170.0)  # the paper's site
MAX_SIM_DURATION_S = 3600.0
MAX_SIM_SATELLITES = 100
_SIM_BYTES_PER_SAMPLE = {"cu8": 2, "sigmf": 2, "cf32": 8}


def _check_range(name: str, value, lo: float, hi: float, unit: str = "") -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and lo <= value <= hi):
        raise UserInputError(f"{name}: {value!r}{' ' + unit if unit else ''} is out of range; "
                             f"expected a number in [{lo:g}, {hi:g}]")


def _check_simulation(args: argparse.Namespace) -> None:
    """Refuse a synthetic capture that cannot be made, before anything is computed or written."""
    from leonav_runtime.beacons import capture_io

    _check_range("--duration", args.duration, 1e-3, MAX_SIM_DURATION_S, "s")
    _check_range("--sim-rate", args.sim_rate, capture_io.MIN_SAMPLE_RATE_HZ, capture_io.MAX_SAMPLE_RATE_HZ, "Hz")
    _check_range("--n-sats", args.n_sats, 1, MAX_SIM_SATELLITES)
    _check_range("--cn0", args.cn0, -50.0, 150.0, "dB-Hz")
    _check_range("--lo-offset", args.lo_offset, -capture_io.MAX_FREQ_HZ, capture_io.MAX_FREQ_HZ, "Hz")
    _check_range("--lo-drift", args.lo_drift, -1e6, 1e6, "Hz/s")
    _check_range("--seed", args.seed, 0, 2**63 - 1)
    if not 1 <= args.tones <= 9:
        raise UserInputError(f"--tones: expected 1..9 tones per satellite, got {args.tones}")
    need = args.duration * args.sim_rate * _SIM_BYTES_PER_SAMPLE[args.sim_format]
    folder = Path(args.capture).resolve().parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    free = shutil.disk_usage(folder).free
    if need > 0.9 * free:
        raise UserInputError(f"--duration/--sim-rate: the synthetic capture would take {need / 1e9:.3g} GB; "
                             f"{free / 1e9:.3g} GB are free in {folder}")


def _check_long_enough(cfg, duration_s: float, sample_rate_hz: float, where: str) -> None:
    """Refuse a capture too short to give any satellite the epochs association needs."""
    from leonav_runtime.beacons.pipeline import min_capture_s

    need = min_capture_s(cfg, sample_rate_hz)
    if duration_s < need:
        raise UserInputError(
            f"{where}: the capture lasts {duration_s:.3g} s; association needs at least {need:.2f} s "
            f"({cfg.association.min_epochs} epochs {cfg.meas_interval_s:g} s apart (--interval), each fitted "
            f"over +/-{cfg.fit_half_window_s:g} s, plus one FFT slice): record a longer capture "
            "(10 s or more is better)")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "beacons",
        help="Starlink beacon capture -> Doppler-rate measurements with satellite IDs",
        description=(
            "Read an IQ capture of the Starlink Ku-band beacon tones (RTL-SDR raw cu8, SigMF, or "
            "complex64), build a band-limited waterfall, track the tone ridges, estimate Doppler and "
            "Doppler-rate (local quadratic fit with sigma), predict every satellite above the elevation "
            "mask from the element sets with the symbolic measurement model, group the parallel tones of "
            "each satellite (comb spaced 43.9495 kHz) and associate the combs to satellites jointly, with "
            "one LO offset and drift for the whole capture (the drift is removed from the rates written "
            "for the filter). Writes associations.csv, "
            "doppler_rate_measurements.csv (the filter's input; columns in "
            "doppler_rate_measurements.columns.txt), summary.json and, last, waterfall.png (skipped with "
            "--no-figures). With --simulate, "
            "first writes a synthetic capture to CAPTURE from the element sets (or the built-in "
            "Walker constellation) and then processes it. "
            "Minimum capture length: a satellite is associated from at least 2 measurement epochs, each "
            "fitted over +/-1 s of ridge, so a capture must last 2 s + 2 x --interval + one FFT slice "
            "(about 4.1 s at the defaults; 10 s or more gives steadier rates); a shorter one is refused."
        ),
    )
    p.add_argument("capture", metavar="CAPTURE",
                   help="capture file: .cu8/.bin (rtl_sdr), .sigmf-meta/.sigmf-data, .cf32; raw files take "
                        "metadata from CAPTURE.json, a sibling .sigmf-meta, or the options below")
    p.add_argument("--tle", action="append", default=[], metavar="FILE",
                   help="TLE/3LE/OMM element file (repeatable); required unless --simulate")
    p.add_argument("--lat", type=float, default=ROCHESTER_DEG[0], metavar="DEG",
                   help="receiver latitude, deg (default: the paper's Rochester site %(default).7f)")
    p.add_argument("--lon", type=float, default=ROCHESTER_DEG[1], metavar="DEG",
                   help="receiver longitude, deg east (default %(default).7f)")
    p.add_argument("--alt", type=float, default=ROCHESTER_DEG[2], metavar="M",
                   help="receiver height above the WGS84 ellipsoid, m (default %(default)g)")
    p.add_argument("--start", metavar="ISO-UTC", default=None,
                   help="UTC time of the first sample (overrides the capture metadata; needed for raw "
                        "files without metadata)")
    p.add_argument("--format", choices=["cu8", "ci8", "cf32", "sigmf"], default=None,
                   help="sample format when the suffix does not tell")
    p.add_argument("--sample-rate", type=float, default=None, metavar="HZ", help="sample rate, Hz")
    p.add_argument("--center-freq", type=float, default=None, metavar="HZ",
                   help="SDR tuned frequency (the LNB IF), Hz, e.g. 1.575e9")
    p.add_argument("--lnb-lo", type=float, default=None, metavar="HZ",
                   help="nominal LNB local oscillator, Hz (default 9.75e9, universal LNB low band)")
    p.add_argument("--tone-freq", type=float, default=STARLINK_BEACON_HZ, metavar="HZ",
                   help="nominal RF tone frequency the Doppler refers to, Hz (default %(default)g)")
    p.add_argument("--mask", type=float, default=STARLINK_MASK_DEG, metavar="DEG",
                   help="elevation mask for candidate satellites, deg (default %(default)g, the paper's)")
    p.add_argument("--fft-size", type=int, default=None, metavar="N",
                   help="STFT length (default: power of two closest to 16 ms of samples)")
    p.add_argument("--band", type=float, default=1.2e6, metavar="HZ",
                   help="width of the tones region kept around the centre, Hz (default %(default)g: "
                        "+/-260 kHz Doppler plus the LO offset)")
    p.add_argument("--dc-notch", type=float, default=0.0, metavar="HZ",
                   help="ignore +/- this around 0 Hz (RTL-SDR DC spike); default off")
    p.add_argument("--interval", type=float, default=1.0, metavar="S",
                   help="spacing of the Doppler-rate measurement epochs, s (default %(default)g)")
    p.add_argument("--keep-drift", action="store_true",
                   help="do not remove the fitted common LO drift from the rates (it is still reported); "
                        "e.g. for a moving receiver, whose motion the static-site prediction does not know")
    p.add_argument("--no-figures", action="store_true",
                   help="do not draw waterfall.png (skips matplotlib and the drawing, about 1 s of CPU); "
                        "the CSV files and summary.json are the same as with the figure")
    p.add_argument("--carrier", action="store_true",
                   help="also track the carrier phase of every associated tone (aided FLL-assisted PLL, "
                        "0.1 s epochs; a second pass over the capture) and write carrier_phase.csv "
                        "(columns in carrier_phase.columns.txt); off by default")
    sim = p.add_argument_group("simulation (--simulate)")
    sim.add_argument("--simulate", action="store_true",
                     help="write a synthetic capture to CAPTURE first, then process it")
    sim.add_argument("--duration", type=float, default=20.0, metavar="S",
                     help="capture length, s (default 20; at least the minimum below)")
    sim.add_argument("--sim-rate", type=float, default=2.4e6, metavar="HZ",
                     help="synthetic sample rate, Hz (default 2.4e6)")
    sim.add_argument("--cn0", type=float, default=40.0, metavar="DBHZ",
                     help="tone carrier-to-noise density C/N0, dB-Hz (default %(default)g)")
    sim.add_argument("--n-sats", type=int, default=5, metavar="N", help="satellites (tones) to put in (default 5)")
    sim.add_argument("--lo-offset", type=float, default=35e3, metavar="HZ", help="LNB LO error at t=0, Hz")
    sim.add_argument("--lo-drift", type=float, default=0.3, metavar="HZ/S", help="LNB LO drift, Hz/s")
    sim.add_argument("--tones", type=int, default=1, metavar="N",
                     help="tones per satellite, centred on the channel, 43.9495 kHz apart (default 1; "
                          "a real channel has 9); tones beyond the band are left out")
    sim.add_argument("--seed", type=int, default=0, help="random seed (satellite choice, noise)")
    sim.add_argument("--sim-format", choices=["cu8", "sigmf", "cf32"], default="sigmf",
                     help="file format of the synthetic capture (default sigmf: CAPTURE's stem + .sigmf-data "
                          "and .sigmf-meta; cu8/cf32 write the raw file + CAPTURE.json)")
    output.add_out_argument(p)
    p.set_defaults(func=run)


class _LazyBar:
    """A progress bar (common.progress) created at the first tick: an error before any sample leaves no bar behind."""

    def __init__(self, total: int, desc: str):
        self.total, self.desc, self.bar = total, desc, None

    def update(self, n: int) -> None:
        if self.bar is None:
            from leonav_runtime.common.progress import progress as make_progress

            self.bar = make_progress(self.total, self.desc, "S", unit_scale=True, leave=False)
        self.bar.update(n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _progress(total: int, desc: str):
    bar = _LazyBar(total, desc)
    return bar, bar.update


def run(args: argparse.Namespace) -> int:
    from leonav_runtime.beacons import capture_io, pipeline
    from leonav_runtime.beacons.predict import Site

    _check_range("--lat", args.lat, -90.0, 90.0, "deg")
    _check_range("--lon", args.lon, -180.0, 360.0, "deg")
    if not (math.isfinite(args.alt) and -11_000 <= args.alt <= 1e6):
        raise UserInputError(f"--alt: {args.alt!r} out of range; expected metres in [-11000, 1e6]")
    site = Site.from_degrees(args.lat, args.lon, args.alt)
    try:
        start = capture_io.parse_utc(args.start, "--start", require_zone=True) if args.start else None
    except OverflowError:  # e.g. year 1 with a positive UTC offset
        start = _dt.datetime.min.replace(tzinfo=_dt.timezone.utc)
    if start is not None and not 1900 <= start.year < 2200:
        raise UserInputError(f"--start: {args.start!r} is outside 1900..2200; expected a time such as "
                             "2026-02-23T06:00:00Z")
    cfg = pipeline.PipelineConfig(f_c_hz=args.tone_freq, band_hz=args.band, fft_size=args.fft_size,
                                  dc_notch_hz=args.dc_notch, meas_interval_s=args.interval, mask_deg=args.mask,
                                  waterfall_image=not args.no_figures)
    cfg.association.remove_drift = not args.keep_drift
    pipeline.validate_config(cfg)  # option values, before any file is read or written
    if args.simulate:
        _check_simulation(args)
        pipeline.validate_config(cfg, args.sim_rate)
        _check_long_enough(cfg, args.duration, args.sim_rate, "--duration")
    out_dir = output.results_dir(args.out, "beacons")
    if args.tle:
        from leonav_runtime.orbits.elements import load_element_files

        elements = load_element_files(args.tle)
    elif args.simulate:
        from leonav_runtime.orbits import default_elements

        if start is None:
            start = _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0)
        elements = default_elements(start)["starlink"]
    else:
        raise UserInputError("--tle: give the element sets (TLE/3LE/OMM) of the capture's day; "
                             "association needs them (or use --simulate)")

    if args.simulate:
        from leonav_runtime.beacons import synth   # SciPy's interpolation: only to synthesize

        if start is None:
            newest = max(elements.epochs_utc)
            start = newest.replace(microsecond=0) + _dt.timedelta(seconds=1)
        sim_cfg = synth.SynthConfig(duration_s=args.duration, sample_rate_hz=args.sim_rate, cn0_dbhz=args.cn0,
                                lo_offset_hz=args.lo_offset, lo_drift_hz_s=args.lo_drift,
                                n_satellites=args.n_sats, seed=args.seed, f_c_hz=args.tone_freq,
                                tones_per_satellite=args.tones, full_comb_in_band=False)
        bar, tick = _progress(int(sim_cfg.duration_s * sim_cfg.sample_rate_hz), "synthesizing")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # stale-element warnings are reported in summary.json
            try:
                capture = Path(args.capture)
                if args.sim_format == "sigmf" and capture.suffix.lower() in (".cu8", ".bin", ".cf32", ".raw"):
                    capture = capture.with_suffix("")  # sim.cu8 -> sim.sigmf-data + sim.sigmf-meta
                info, truth = synth.write_synthetic_capture(capture, elements, site, start, sim_cfg,
                                                            args.sim_format, progress=tick)
            except UserInputError:
                raise
            except ValueError as exc:
                raise UserInputError(f"--simulate: {exc}") from None
            finally:
                bar.close()
        print(f"synthetic capture: {info.path} ({info.n_samples} samples, {info.duration_s:g} s) with "
              f"{', '.join(f'{n} ({i})' for n, i in zip(truth.names, truth.norad_ids))}")
        output.write_json(out_dir / "synthetic_truth.json", truth.describe())
    else:
        info = capture_io.open_capture(args.capture, args.format, sample_rate_hz=args.sample_rate,
                                       center_freq_hz=args.center_freq, lnb_lo_hz=args.lnb_lo, start_utc=start)
    if info.trailing_bytes:
        import logging

        logging.getLogger("leonav.beacons").warning(
            f"{info.path}: {info.trailing_bytes} trailing byte(s) after the last complete sample ignored "
            "(truncated file?)")
    if info.start_utc is None:
        raise UserInputError(f"{info.path}: capture start time unknown; give --start ISO-UTC "
                             "(or core:datetime / start_utc in the metadata)")
    pipeline.validate_config(cfg, info.sample_rate_hz)
    _check_long_enough(cfg, info.duration_s, info.sample_rate_hz, str(info.path))
    bar, tick = _progress(info.n_samples, "processing")
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            res = pipeline.process_capture(info, elements, site, cfg, progress=tick)
    finally:
        bar.close()
    paths = pipeline.write_outputs(res, out_dir, figures=False)  # the figure last, after the numbers
    if args.carrier:
        from leonav_runtime.beacons import carrier_hook

        skipped: list[str] = []
        tracked = carrier_hook.track_result(res, skipped=skipped)
        paths.update(carrier_hook.write_carrier_csv(res, tracked, out_dir))
        print(carrier_hook.summary_line(tracked, skipped))
    s = pipeline.summary(res)
    notes = res.track_stats.notes()
    if caught or notes:
        s["warnings"] = sorted({str(w.message) for w in caught}) + notes
        output.write_json(paths["summary"], {"provenance": json.loads(paths["summary"].read_text())["provenance"], **s})
    for w in {str(w.message): w for w in caught}.values():  # shown once each (the CLI dedupes stale ones)
        warnings.warn(str(w.message), w.category, stacklevel=1)
    for note in notes:
        print(f"note: {note}")
    c, r = s["counts"], s["rate_residual_abs_hz_s"]
    print(f"{info.path.name}: {info.duration_s:.1f} s at {info.sample_rate_hz / 1e6:g} MS/s, "
          f"{s['candidates_above_mask']} satellites above {args.mask:g} deg")
    if res.reason:
        print(f"no measurements: {res.reason}")
    print(f"ridges {c['ridges']} in {c.get('combs', 0)} comb(s): associated {c['associated']} "
          f"({c.get('satellites_associated', 0)} satellites), ambiguous {c['ambiguous']}, "
          f"unassociated {c['unassociated']}")
    lo = res.lo
    if lo.n_combs:
        mod = "" if lo.pinned else f" (modulo {lo.ambiguity_hz / 1e3:g} kHz)"
        print(f"common LO: offset {lo.offset_hz / 1e3:+.3f} kHz{mod}, drift {lo.drift_hz_s:+.3f} "
              f"+/- {lo.sigma_drift_hz_s:.3f} Hz/s from {lo.n_combs} comb(s), "
              f"{'removed from the rates' if lo.drift_removed else 'not removed'}"
              f"{'; ' + lo.note if lo.note and not lo.drift_removed else ''}")
    for a in res.associations:
        tag = f"{a.name} ({a.norad_id})" if a.status != "unassociated" else "-"
        extra = (f" cost {a.cost:.2f}, ratio {a.ambiguity_ratio:.1f}, LO offset {a.lo_offset_hz / 1e3:+.3f} kHz, "
                 f"rms rate residual {a.rms_rate_hz_s:.2f} Hz/s") if a.status != "unassociated" else ""
        if a.comb_tones > 1 or a.tone_index:
            extra = f" comb {a.comb_id} tone {'?' if a.tone_index is None else f'{a.tone_index:+d}'}" + (
                extra if a.carrier else "")
        print(f"  ridge {a.ridge_id}: {a.status:12s} {tag}{extra}{'; ' + a.reason if a.reason else ''}")
    if r["n"]:
        print(f"|delta alpha| over {r['n']} epochs: median {r['median']:.2f}, mean {r['mean']:.2f}, "
              f"max {r['max']:.2f} Hz/s (paper: 0.8, 1.46, 3.4)")
    if not args.no_figures:
        pipeline.plot_waterfall(res, out_dir / "waterfall.png")
    print(f"results in {out_dir}/")
    return 0
