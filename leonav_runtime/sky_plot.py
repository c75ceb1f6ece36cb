"""The sky figure: polar tracks of the visible satellites and the visible count over time."""
from __future__ import annotations

import math

import numpy as np

from leonav_runtime.sky import PLOT_TRACK_SPAN_S, SkyView

CONSTELLATION_COLOURS = {"starlink": "tab:blue", "gps": "tab:red", "unknown": "tab:green"}


def _colour(name: str, i: int) -> str:
    fallback = ["tab:green", "tab:purple", "tab:orange", "tab:brown"]
    return CONSTELLATION_COLOURS.get(name, fallback[i % len(fallback)])


def plot(view: SkyView, path) -> None:
    """Write the two-panel figure: polar sky tracks (left), visible count vs time (right)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(14, 6.5))
    ax_sky = fig.add_subplot(1, 2, 1, projection="polar")
    ax_cnt = fig.add_subplot(1, 2, 2)
    ax_sky.set_theta_zero_location("N")
    ax_sky.set_theta_direction(-1)  # azimuth clockwise from North (map-style sky plot)
    ax_sky.set_rlabel_position(112.5)  # elevation labels between E and SE, away from the tracks' labels
    ax_sky.set_rlim(0, 90)
    ax_sky.set_rticks([0, 30, 60, 90])
    ax_sky.set_yticklabels(["90°", "60°", "30°", "0°"], fontsize=8)
    ax_sky.set_thetagrids(range(0, 360, 45), ["N", "NE", "E", "SE", "S", "SW", "W", "NW"])
    nt = view.t_s.size
    n_track = int(np.searchsorted(view.t_s, view.t_s[0] + PLOT_TRACK_SPAN_S, side="right"))
    theta_circle = np.linspace(0, 2 * np.pi, 361)
    span_s = view.t_s[-1] - view.t_s[0]
    t_unit, t_scale = ("h", 3600.0) if span_s >= 3 * 3600 else ("min", 60.0) if span_s >= 300 else ("s", 1.0)
    t_axis = view.t_s / t_scale
    # Largest constellation first, so the few GPS tracks are drawn over the Starlink ones.
    order = sorted(view.constellations.items(), key=lambda item: -item[1].n_loaded)
    for i, (name, c) in enumerate(order):
        colour = _colour(name, i)
        mask_deg = math.degrees(c.mask_rad)
        z = 2 + 2 * i
        ax_sky.plot(theta_circle, np.full_like(theta_circle, 90 - mask_deg), ls="--", lw=1.0, color=colour, alpha=0.8)
        sats, az, el, vis = c.dense(nt)
        az, el = az[:, :n_track], el[:, :n_track]
        # Unwrap azimuth so a track crossing North is drawn across it instead of around the
        # whole circle; NaN (hidden, or the separator column) breaks the line. All tracks of
        # a constellation go into one line: one artist per satellite is ~10x slower.
        for row in range(sats.size):
            finite = np.isfinite(az[row])
            az[row, finite] = np.unwrap(az[row, finite])
        sep = np.full((sats.size, 1), np.nan)
        ax_sky.plot(
            np.hstack([az, sep]).ravel(), np.hstack([90 - np.degrees(el), sep]).ravel(),
            lw=0.8 if c.n_loaded > 100 else 1.4, color=colour, alpha=0.55 if c.n_loaded > 100 else 0.9, zorder=z,
        )
        now = c.t_index == 0
        label = f"{name} (mask {mask_deg:g}°, {int(c.count[0])} visible at start)"
        ax_sky.scatter(c.az_rad[now], 90 - np.degrees(c.el_rad[now]), s=16, color=colour, zorder=z + 1, label=label,
                       edgecolors="white", linewidths=0.4)
        ax_cnt.step(t_axis, c.count, where="post", color=colour, lw=1.6, label=f"{name} (≥ {mask_deg:g}°)")
        k = int(np.argmin(c.count))
        ax_cnt.plot(t_axis[k], c.count[k], "v", color=colour, ms=9)
        ax_cnt.annotate(
            f"min {int(c.count[k])}",
            (t_axis[k], c.count[k]),
            textcoords="offset points",
            xytext=(8, -4),
            color=colour,
            fontsize=9,
        )
    track_span = view.t_s[n_track - 1] - view.t_s[0]
    ax_sky.set_title(
        f"Sky above the masks (dashed): tracks over the first {track_span / 60:.3g} min, dots at start\n"
        "elevation 90° at the centre, 0° at the rim; azimuth clockwise from North",
        fontsize=10,
        pad=18,
    )
    ax_sky.legend(loc="upper center", bbox_to_anchor=(0.5, -0.06), fontsize=8, frameon=False)
    ax_cnt.axhline(4, color="grey", lw=0.8, ls=":")
    ax_cnt.text(t_axis[-1], 4, "4 needed for a fix ", va="bottom", ha="right", fontsize=8, color="grey")
    ax_cnt.set_xlabel(f"time since start [{t_unit}]")
    ax_cnt.set_ylabel("visible satellites")
    ax_cnt.set_ylim(bottom=0)
    ax_cnt.grid(alpha=0.3)
    ax_cnt.legend(fontsize=9)
    lat, lon = math.degrees(view.site.lat_rad), math.degrees(view.site.lon_rad)
    ax_cnt.set_title(
        f"Visible satellites at {lat:.4f}°, {lon:.4f}°, {view.site.h_m:g} m\n"
        f"from {view.epoch_utc:%Y-%m-%d %H:%M:%S} UTC",
        fontsize=10,
    )
    fig.subplots_adjust(left=0.04, right=0.98, top=0.86, bottom=0.13, wspace=0.18)  # fixed: tight_layout costs a draw
    fig.savefig(path, dpi=120)
    plt.close(fig)
