"""waterfall.png: the capture's spectrogram (dB above the noise floor, with a colour bar),
the tracked ridges coloured by comb, one label per satellite, and the predicted Doppler
curves of the associated satellites' tones (dotted) drawn over it."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from leonav_runtime.common import plot_style as ps
from leonav_runtime.gen.constants import COMB_SPACING_HZ


def _predicted_baseband_hz(res, a, t_s: np.ndarray, tone: int) -> np.ndarray | None:
    """Predicted baseband frequency (Hz) of tone `tone` of the satellite of association `a`:
    predicted Doppler + the common LO offset (or the comb's own) + tone spacing, referred to
    the capture's centre frequency."""
    pred = res.predictions
    if pred is None or a.sat_row < 0 or pred.t_s.size < 4:
        return None
    d = pred.at(t_s)[0][a.sat_row]
    lo = res.lo.at(t_s) if np.isfinite(res.lo.offset_hz) else a.lo_offset_hz
    if not np.all(np.isfinite(lo)):
        return None
    return d + lo + tone * COMB_SPACING_HZ - (res.info.rf_center_hz - res.f_c_hz)


def plot_waterfall(res, path: Path, summary_counts: dict) -> Path:
    """Write the waterfall figure of a `PipelineResult`; returns the path."""
    plt = ps.pyplot()
    t, f, img = res.waterfall
    fig, ax = plt.subplots(figsize=(ps.COLUMN_WIDTH_IN * 2, 4.2))  # spans both columns: 1 MHz of tones
    if img.size:
        vmax = max(float(np.percentile(img, 99.9)), 6.0)
        im = ax.imshow(img, aspect="auto", origin="lower", cmap="viridis", vmin=0, vmax=vmax,
                       extent=[f[0] / 1e3, f[-1] / 1e3, t[0], t[-1]], interpolation="nearest")
        fig.colorbar(im, ax=ax, pad=0.01, fraction=0.04).set_label("power above the noise floor [dB]")
    comb_ids = sorted({a.comb_id for a in res.associations if a.comb_id >= 0})
    cmap = plt.get_cmap("Set1" if len(comb_ids) <= 9 else "tab20")
    comb_colour = {c: cmap(i % cmap.N) for i, c in enumerate(comb_ids)}
    labelled: dict[tuple, tuple] = {}   # one label per satellite (or per unassociated comb)
    t_top = float(t[-1]) if t.size else 1.0
    for ridge, a in zip(res.ridges, res.associations):
        colour = comb_colour.get(a.comb_id, "red") if a.status != "unassociated" else "red"
        ls = "-" if a.status == "associated" else (0, (3, 2))
        ax.plot(ridge.f_hz / 1e3, ridge.t_s, color=colour, lw=0.8, alpha=0.85, ls=ls)
        key = (a.norad_id,) if a.status == "associated" else ("comb", a.comb_id, ridge.ridge_id if a.comb_id < 0 else 0)
        if a.status == "associated" and a.tone_index is not None:
            fp = _predicted_baseband_hz(res, a, ridge.t_s, int(a.tone_index))
            if fp is not None:
                ax.plot(fp / 1e3, ridge.t_s, color="white", lw=0.7, ls=(0, (1, 1.5)), alpha=0.9)
        x = float(np.median(ridge.f_hz)) / 1e3
        if key not in labelled or (a.tone_index == 0):  # prefer the central tone's position
            text = f"{a.name} ({a.norad_id})" if a.status == "associated" else (
                f"{a.name}? / {a.second_name}?" if a.status == "ambiguous" else "unassociated")
            labelled[key] = (x, colour, text)
    # labels above the image in staggered rows so neighbouring satellites do not collide
    for row, (x, colour, text) in enumerate(sorted(labelled.values())):
        ax.annotate(text, (x, t_top), xytext=(0, 3 + 9 * (row % 3)), textcoords="offset points", ha="center",
                    va="bottom", fontsize=6, color=colour, annotation_clip=False,
                    bbox={"boxstyle": "round,pad=0.15", "fc": "black", "alpha": 0.75, "lw": 0})
    info = res.info
    ax.set_xlabel(f"baseband frequency [kHz], 0 = {info.rf_center_hz / 1e9:.6f} GHz RF "
                  f"({info.center_freq_hz / 1e6:.3f} MHz IF)")
    ax.set_ylabel("time since capture start [s]")
    ax.grid(False)
    start = info.start_utc.isoformat() if info.start_utc else "unknown start"
    c = summary_counts
    ax.set_title(f"{info.path.name}  {start}: ridges {c['ridges']}, associated {c['associated']}, "
                 f"ambiguous {c['ambiguous']}, unassociated {c['unassociated']}\n"
                 "ridges coloured by comb (dashed: not associated), white dotted: predicted Doppler of "
                 "each associated tone", fontsize=7, pad=34)
    ps.save(fig, path)
    return Path(path)
