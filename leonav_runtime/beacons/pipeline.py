"""Capture -> waterfall -> ridges -> Doppler / Doppler-rate -> satellite association -> files.

`process_capture` streams the capture once (bounded memory), tracks the ridges, fits the
Doppler-rate measurements, predicts every visible satellite with the symbolic model, groups
the ridges into per-satellite tone combs and associates them with one LO offset and drift
for the whole capture (`associate.associate_capture`). `write_outputs` writes associations.csv,
doppler_rate_measurements.csv (the filter's input), summary.json and, last, waterfall.png.
"""
from __future__ import annotations

import dataclasses
import datetime as _dt
import math
from pathlib import Path
from typing import Callable

import numpy as np

from leonav_runtime.beacons import capture_io
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.beacons.associate import Association, AssociationConfig, associate_capture
from leonav_runtime.beacons.comb import Comb
from leonav_runtime.beacons.lo_fit import LoEstimate
from leonav_runtime.beacons.doppler import RidgeMeasurements, ridge_measurements
from leonav_runtime.beacons.predict import DEFAULT_MASK_DEG, STARLINK_BEACON_HZ, Predictions, Site, predict_visible
from leonav_runtime.beacons.ridges import Ridge, TrackerConfig, TrackStats, RidgeTracker
from leonav_runtime.beacons.waterfall import StftConfig, WaterfallImage, band_bins, iter_spectra, n_slices

PAPER_RESIDUALS_HZ_S = {"median": 0.8, "mean": 1.46, "max": 3.4}  # paper, five matched beacons

MEASUREMENT_COLUMNS = [
    ("t_s", "s", "measurement epoch, seconds since the capture start (epoch_utc)"),
    ("epoch_utc", "ISO-8601", "the same epoch as UTC time"),
    ("norad_id", "-", "NORAD catalogue number of the associated satellite"),
    ("name", "-", "satellite name from the element set"),
    ("doppler_rate_hz_s", "Hz/s", "measured Doppler rate (local quadratic fits, averaged over the comb's tones), "
                                  "common LO drift removed when lo_drift_hz_s is nonzero"),
    ("sigma_hz_s", "Hz/s", "1-sigma of the rate from the fit residuals (and of the removed drift)"),
    ("doppler_hz", "Hz", "measured Doppler of the central tone incl. the LNB LO offset "
                         "(f_baseband + rf_center - f_tone - tone_index * spacing)"),
    ("sigma_doppler_hz", "Hz", "1-sigma of the Doppler fit"),
    ("lo_offset_hz", "Hz", "common LO offset of the capture at this epoch, b0 + b1 t (measured - predicted "
                           "Doppler = minus the LNB LO error); modulo the tone spacing unless summary.json "
                           "lo.pinned"),
    ("predicted_rate_hz_s", "Hz/s", "symbolic-model prediction for the satellite (static receiver at the site)"),
    ("rate_residual_hz_s", "Hz/s", "doppler_rate_hz_s - predicted_rate_hz_s"),
    ("snr_db", "dB", "median per-bin SNR of the ridge in the fit window"),
    ("ridge_id", "-", "ridge number in associations.csv / waterfall.png"),
    ("f_c_hz", "Hz", "nominal RF tone frequency the Doppler refers to"),
    ("lo_drift_hz_s", "Hz/s", "common LO drift b1 removed from doppler_rate_hz_s (0 if not removed; "
                              "summary.json lo says why)"),
    ("comb_id", "-", "tone comb (ridges of one satellite) in associations.csv"),
    ("n_tones", "-", "tones averaged at this epoch"),
]


MIN_FFT_SIZE = 16
MAX_FFT_SIZE = 1 << 22
MIN_BAND_BINS = 8
MIN_INTERVAL_S, MAX_INTERVAL_S = 0.05, 3600.0
MAX_CAPTURE_S = 6 * 3600.0  # one LO offset and drift per capture; longer recordings are split


@dataclasses.dataclass
class PipelineConfig:
    f_c_hz: float = STARLINK_BEACON_HZ
    band_hz: float | None = 1.2e6        # tones region kept around the centre (Doppler + LO offset)
    fft_size: int | None = None          # default: 2^k closest to fs * 16 ms (waterfall.default_fft_size)
    overlap: float = 0.5
    dc_notch_hz: float = 0.0
    meas_interval_s: float = 1.0
    fit_half_window_s: float = 1.0
    mask_deg: float = DEFAULT_MASK_DEG
    chunk_samples: int = 1 << 20
    tracker: TrackerConfig = dataclasses.field(default_factory=TrackerConfig)
    association: AssociationConfig = dataclasses.field(default_factory=AssociationConfig)
    max_duration_s: float = MAX_CAPTURE_S
    waterfall_image: bool = True         # keep the down-sampled image waterfall.png is drawn from


def _finite_in(value, lo: float, hi: float) -> bool:
    try:
        return math.isfinite(float(value)) and lo <= float(value) <= hi
    except (TypeError, ValueError):
        return False


def min_capture_s(cfg: PipelineConfig, sample_rate_hz: float) -> float:
    """Shortest capture (s) from which a satellite can be associated: `min_epochs` epochs on
    the `meas_interval_s` grid, each needing +/-`fit_half_window_s` of ridge, inside the
    span of the STFT slice centres (the capture minus one slice)."""
    stft = StftConfig.for_rate(sample_rate_hz, cfg.band_hz, cfg.fft_size, cfg.overlap, cfg.dc_notch_hz)
    return (stft.fft_size / sample_rate_hz + 2.0 * cfg.fit_half_window_s
            + cfg.association.min_epochs * cfg.meas_interval_s)


def validate_config(cfg: PipelineConfig, sample_rate_hz: float | None = None) -> None:
    """UserInputError naming the `leonav beacons` option when a setting cannot work.

    With `sample_rate_hz`, also checks that the band keeps enough FFT bins to track in.
    """
    if cfg.fft_size is not None and not (isinstance(cfg.fft_size, (int, np.integer))
                                         and MIN_FFT_SIZE <= cfg.fft_size <= MAX_FFT_SIZE):
        raise UserInputError(f"--fft-size: {cfg.fft_size!r}; expected a whole number of samples in "
                             f"{MIN_FFT_SIZE}..{MAX_FFT_SIZE} (default: about 16 ms of samples)")
    if cfg.band_hz is not None and not _finite_in(cfg.band_hz, 1e-300, math.inf):
        raise UserInputError(f"--band: {cfg.band_hz!r} Hz; expected a positive width, e.g. 1.2e6")
    checks = (("--interval", cfg.meas_interval_s, MIN_INTERVAL_S, MAX_INTERVAL_S, "s"),
              ("--dc-notch", cfg.dc_notch_hz, 0.0, math.inf, "Hz"),
              ("--mask", cfg.mask_deg, -90.0, 90.0, "deg"),
              ("--tone-freq", cfg.f_c_hz, 1.0, capture_io.MAX_FREQ_HZ, "Hz"),
              ("fit_half_window_s", cfg.fit_half_window_s, 0.01, 600.0, "s"),
              ("overlap", cfg.overlap, 0.0, 0.95, ""))
    for name, value, lo, hi, unit in checks:
        if not _finite_in(value, lo, hi):
            raise UserInputError(f"{name}: {value!r} {unit}".rstrip() + f"; expected a number in [{lo:g}, {hi:g}]")
    if sample_rate_hz is not None:
        stft = StftConfig.for_rate(sample_rate_hz, cfg.band_hz, cfg.fft_size, cfg.overlap, cfg.dc_notch_hz)
        n_bins = band_bins(stft, sample_rate_hz)[0].size
        if n_bins < MIN_BAND_BINS:
            raise UserInputError(
                f"--band: {stft.band_hz:g} Hz keeps {n_bins} FFT bins of {sample_rate_hz / stft.fft_size:g} Hz; "
                f"expected at least {MIN_BAND_BINS} (widen --band or use a larger --fft-size)")


@dataclasses.dataclass
class PipelineResult:
    info: capture_io.CaptureInfo
    stft: StftConfig
    ridges: list[Ridge]
    track_stats: TrackStats
    measurements: list[RidgeMeasurements]
    predictions: Predictions | None
    associations: list[Association]
    waterfall: tuple[np.ndarray, np.ndarray, np.ndarray]
    reason: str = ""   # why the result is empty, if it is
    # `measurements` are what goes to the filter: for an associated comb its carrier ridge holds
    # the combined, drift-corrected measurement and its other tones hold none (empty);
    # `ridge_measurements` are every ridge's own fits.
    ridge_measurements: list[RidgeMeasurements] = dataclasses.field(default_factory=list)
    combs: list[Comb] = dataclasses.field(default_factory=list)
    lo: LoEstimate = dataclasses.field(default_factory=LoEstimate)
    f_c_hz: float = STARLINK_BEACON_HZ  # beacon carrier the Doppler is referred to (Hz)

    def by_ridge(self) -> dict[int, tuple[Ridge, RidgeMeasurements, Association]]:
        return {r.ridge_id: (r, m, a) for r, m, a in zip(self.ridges, self.measurements, self.associations)}


def extract_ridges(info: capture_io.CaptureInfo, cfg: PipelineConfig,
                   progress: Callable[[int], None] | None = None):
    """Stream the capture through the STFT and the tracker: (ridges, stats, stft cfg, waterfall image)."""
    validate_config(cfg, info.sample_rate_hz)
    stft = StftConfig.for_rate(info.sample_rate_hz, cfg.band_hz, cfg.fft_size, cfg.overlap, cfg.dc_notch_hz)
    _, f_hz = band_bins(stft, info.sample_rate_hz)
    tracker = RidgeTracker(f_hz, cfg.tracker)
    # memory flat in capture length; not kept when no figure will be drawn
    image = WaterfallImage(f_hz, total_rows=n_slices(info.n_samples, stft)) if cfg.waterfall_image else None

    def blocks():
        for b in capture_io.iter_chunks(info, cfg.chunk_samples):
            yield b
            if progress:
                progress(b.size)

    for blk in iter_spectra(blocks(), stft, info.sample_rate_hz):
        tracker.add_block(blk)
        if image is not None:
            image.add(blk)
    ridges = tracker.finish()
    no_image = (np.zeros(0), f_hz, np.zeros((0, f_hz.size), np.float32))
    return ridges, tracker.stats, stft, image.image() if image is not None else no_image


def process_capture(info: capture_io.CaptureInfo, elements, site: Site, cfg: PipelineConfig | None = None,
                    progress: Callable[[int], None] | None = None) -> PipelineResult:
    """Run the whole pipeline on one capture (see module docstring)."""
    cfg = cfg or PipelineConfig()
    validate_config(cfg, info.sample_rate_hz)
    if info.duration_s > cfg.max_duration_s:
        raise UserInputError(f"{info.path}: capture lasts {info.duration_s:.0f} s, more than the "
                             f"{cfg.max_duration_s:g} s processed as one recording (one LO offset and drift); "
                             "split it into shorter files")
    stft = StftConfig.for_rate(info.sample_rate_hz, cfg.band_hz, cfg.fft_size, cfg.overlap, cfg.dc_notch_hz)
    empty_img = (np.zeros(0), np.zeros(0), np.zeros((0, 0)))
    if info.n_samples < stft.fft_size:
        return PipelineResult(info, stft, [], TrackStats(), [], None, [], empty_img,
                              f"capture holds {info.n_samples} samples, fewer than one FFT of {stft.fft_size}")
    ridges, stats, stft, image = extract_ridges(info, cfg, progress)
    meas = [ridge_measurements(r, info.rf_center_hz, cfg.f_c_hz, cfg.meas_interval_s, cfg.fit_half_window_s)
            for r in ridges]
    if not ridges:
        return PipelineResult(info, stft, [], stats, [], None, [], image,
                              f"no tone ridge found: {stats.births} candidate peaks above the detection "
                              f"threshold, none lasting {cfg.tracker.min_duration_s:g} s")
    if info.start_utc is None:
        raise UserInputError(f"{info.path}: capture start time unknown: association needs it (give --start)")
    pred = predict_visible(elements, site, info.start_utc, info.duration_s, mask_deg=cfg.mask_deg,
                           f_c_hz=cfg.f_c_hz)
    ca = associate_capture(meas, pred, cfg.association)
    filt = [m if a.status != "associated" else ca.filter_measurements[m.ridge_id] if a.carrier else _empty(m)
            for m, a in zip(meas, ca.associations)]
    return PipelineResult(info, stft, ridges, stats, filt, pred, ca.associations, image, "", meas, ca.combs, ca.lo,
                          cfg.f_c_hz)


def _empty(m: RidgeMeasurements) -> RidgeMeasurements:
    z = np.zeros(0)
    return RidgeMeasurements(m.ridge_id, z, z, z, z, z, np.zeros(0, int), z)


def _stats(values: np.ndarray) -> dict:
    v = np.abs(np.asarray(values, float))
    if v.size == 0:
        return {"n": 0, "median": None, "mean": None, "max": None}
    return {"n": int(v.size), "median": float(np.median(v)), "mean": float(np.mean(v)), "max": float(np.max(v))}


def summary(res: PipelineResult) -> dict:
    """Counts and residual statistics (|delta alpha| over associated measurement epochs)."""
    counts = {"ridges": len(res.ridges)}
    for status in ("associated", "ambiguous", "unassociated"):
        counts[status] = sum(a.status == status for a in res.associations)
    counts["combs"] = len(res.combs)
    # one entry per associated comb: its combined measurement is what the filter gets
    assoc = [a for a in res.associations if a.status == "associated" and a.carrier]
    counts["satellites_associated"] = len(assoc)
    per_epoch = np.concatenate([a.rate_residual_hz_s for a in assoc]) if assoc else np.zeros(0)
    per_ridge = np.asarray([np.median(np.abs(a.rate_residual_hz_s)) for a in assoc])
    info = res.info
    fs = info.sample_rate_hz
    return {
        "capture": info.describe(),
        "stft": {"fft_size": res.stft.fft_size, "hop": res.stft.hop, "bin_hz": fs / res.stft.fft_size,
                 "slice_s": res.stft.fft_size / fs, "band_hz": res.stft.band_hz},
        "counts": counts,
        "tracking": dataclasses.asdict(res.track_stats),
        "candidates_above_mask": 0 if res.predictions is None else len(res.predictions.names),
        "rate_residual_abs_hz_s": _stats(per_epoch),
        "rate_residual_abs_per_ridge_median_hz_s": _stats(per_ridge),
        "rate_residual_signed_mean_hz_s": float(np.mean(per_epoch)) if per_epoch.size else None,
        "lo": res.lo.as_dict(),
        "combs": [{"comb_id": c.comb_id, "ridge_ids": c.ridge_ids, "relative_tone_index": c.rel_index,
                   "carrier_ridge_id": c.carrier_ridge_id, "tones": c.tones} for c in res.combs],
        "paper_rate_residual_abs_hz_s": PAPER_RESIDUALS_HZ_S,
        "reason_empty": res.reason or None,
        "associations": [{"ridge_id": a.ridge_id, "status": a.status, "reason": a.reason, "norad_id": a.norad_id,
                          "name": a.name, "cost": a.cost, "ambiguity_ratio": a.ambiguity_ratio,
                          "lo_offset_hz": a.lo_offset_hz, "comb_id": a.comb_id, "tone_index": a.tone_index,
                          "carrier": a.carrier} for a in res.associations],
    }


def _iso(start: _dt.datetime | None, t: float) -> str:
    if start is None:
        return ""
    return (start + _dt.timedelta(seconds=float(t))).isoformat().replace("+00:00", "Z")


def write_outputs(res: PipelineResult, out_dir: Path, figures: bool = True) -> dict[str, Path]:
    """associations.csv, doppler_rate_measurements.csv (+ .columns.txt), summary.json, then
    waterfall.png (last, and only with `figures`: the numbers are on disk before matplotlib
    is even imported)."""
    from leonav_runtime.common.output import write_csv, write_json

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    start = res.info.start_utc
    pred = res.predictions
    rows_a, rows_m = [], []
    lo = res.lo
    drift = lo.drift_hz_s if lo.drift_removed else 0.0
    n_tones = {c.carrier_ridge_id: c.n_tones for c in res.combs}
    own = res.ridge_measurements or res.measurements
    for ridge, m0, m, a in zip(res.ridges, own, res.measurements, res.associations):
        tone = "" if a.tone_index is None else a.tone_index
        tail = [a.lo_offset_hz, a.cost, a.ambiguity_ratio, a.second_name, a.second_norad_id, a.comb_id, tone,
                a.comb_tones, int(a.carrier), a.reason]
        pr0 = pr = None
        if pred is not None and a.sat_row >= 0:
            pr0 = pred.at(m0.t_s)[1][a.sat_row] if m0.t_s.size else None
            pr = pred.at(m.t_s)[1][a.sat_row] if m.t_s.size else None
        for k in range(m0.t_s.size):  # every ridge's own fit; rate residual with the drift that went out
            resid = m0.rate_hz_s[k] - drift - pr0[k] if pr0 is not None else math.nan
            rows_a.append([m0.t_s[k], _iso(start, m0.t_s[k]), ridge.ridge_id, a.status, a.name, a.norad_id,
                           m0.doppler_hz[k], m0.rate_hz_s[k], m0.sigma_rate_hz_s[k], resid, *tail])
        if a.status == "associated" and pr is not None:
            lo_t = lo.at(m.t_s) if np.isfinite(lo.offset_hz) else np.full(m.t_s.size, a.lo_offset_hz)
            nt = n_tones.get(ridge.ridge_id, np.ones(m.t_s.size, int))
            for k in range(m.t_s.size):
                rows_m.append([m.t_s[k], _iso(start, m.t_s[k]), a.norad_id, a.name, m.rate_hz_s[k],
                               m.sigma_rate_hz_s[k], m.doppler_hz[k], m.sigma_doppler_hz[k], lo_t[k],
                               pr[k], m.rate_hz_s[k] - pr[k], m.snr_db[k], ridge.ridge_id, res.f_c_hz,
                               drift, a.comb_id, int(nt[k])])
        if m0.t_s.size == 0:
            rows_a.append([math.nan, "", ridge.ridge_id, a.status, a.name, a.norad_id, math.nan, math.nan,
                           math.nan, math.nan, *tail])
    rows_m.sort(key=lambda r: (r[0], r[2]))
    paths = {
        "associations": write_csv(out_dir / "associations.csv",
                                  ["t_s", "epoch_utc", "ridge_id", "status", "name", "norad_id", "doppler_hz",
                                   "doppler_rate_hz_s", "sigma_hz_s", "rate_residual_hz_s", "lo_offset_hz",
                                   "cost", "ambiguity_ratio", "second_name", "second_norad_id", "comb_id",
                                   "tone_index", "comb_tones", "carrier", "reason"], rows_a),
        "measurements": write_csv(out_dir / "doppler_rate_measurements.csv",
                                  [c[0] for c in MEASUREMENT_COLUMNS], rows_m),
    }
    cols = out_dir / "doppler_rate_measurements.columns.txt"
    cols.write_text("".join(f"{n} [{u}]: {d}\n" for n, u, d in MEASUREMENT_COLUMNS))
    paths["columns"] = cols
    from leonav_runtime.common.provenance import provenance

    paths["summary"] = write_json(out_dir / "summary.json", {"provenance": provenance(), **summary(res)})
    if figures:
        paths["waterfall"] = plot_waterfall(res, out_dir / "waterfall.png")
    return paths


def plot_waterfall(res: PipelineResult, path: Path) -> Path:
    """Waterfall (dB above the noise floor) with ridges, satellite labels and predictions."""
    from leonav_runtime.beacons.waterfall_plot import plot_waterfall as draw

    return draw(res, path, summary(res)["counts"])
