"""The sky figure: polar tracks of the visible satellites (labelled) above the visible
count over time, stacked for the paper's column width; times in seconds throughout."""
from __future__ import annotations

import math
import re

import numpy as np

from leonav_runtime.common import plot_style as ps
from leonav_runtime.sky.view import PLOT_TRACK_SPAN_S, SkyView

CONSTELLATION_COLOURS = {"starlink": "tab:blue", "gps": "tab:red", "unknown": "tab:green"}
MAX_LABELS = 14  # per constellation: beyond this the labels would cover the tracks


def _colour(name: str, i: int) -> str:
    fallback = ["tab:green", "tab:purple", "tab:orange", "tab:brown"]
    return CONSTELLATION_COLOURS.get(name, fallback[i % len(fallback)])


def short_label(name: str, norad_id: int) -> str:
    """A short satellite label a reader can look up: G13 for a GPS "(PRN 13)" name, SL-31190 for
    STARLINK-31190, a short name as it is, otherwise the NORAD catalogue number as #58897."""
    prn = re.search(r"PRN\s*0*(\d+)", name)
    if prn:
        return f"G{int(prn.group(1)):02d}"
    starlink = re.fullmatch(r"STARLINK-(\d+)", name.strip(), re.I)
    if starlink:
        return f"SL-{starlink.group(1)}"
    short = name.strip()
    return short if 0 < len(short) <= 12 else f"#{norad_id}"


def _label_rows(az_rad: np.ndarray, el_deg: np.ndarray, min_sep_deg: float = 9.0) -> list[int]:
    """Start dots to label, highest first, skipping dots closer than `min_sep_deg` (on the
    plot) to one already labelled so labels do not overlap; at most `MAX_LABELS`."""
    xy = np.stack([(90 - el_deg) * np.sin(az_rad), (90 - el_deg) * np.cos(az_rad)], 1)
    chosen: list[int] = []
    for k in np.argsort(-el_deg):
        if len(chosen) >= MAX_LABELS:
            break
        if all(np.hypot(*(xy[k] - xy[j])) >= min_sep_deg for j in chosen):
            chosen.append(int(k))
    return chosen


def plot(view: SkyView, path) -> None:
    """Write the figure: polar sky tracks (top), visible count vs time (bottom)."""
    plt = ps.pyplot()
    fig = plt.figure(figsize=(ps.COLUMN_WIDTH_IN, 6.0))
    ax_sky = fig.add_axes((0.06, 0.35, 0.88, 0.58), projection="polar")
    ax_cnt = fig.add_axes((0.14, 0.07, 0.80, 0.19))
    ax_sky.set_theta_zero_location("N")
    ax_sky.set_theta_direction(-1)  # azimuth clockwise from North (map-style sky plot)
    ax_sky.set_rlabel_position(112.5)
    ax_sky.set_rlim(0, 90)
    ax_sky.set_rticks([0, 30, 60, 90])
    ax_sky.set_yticklabels(["90°", "60°", "30°", "0°"])
    ax_sky.set_thetagrids(range(0, 360, 45), ["N", "NE", "E", "SE", "S", "SW", "W", "NW"])
    nt = view.t_s.size
    n_track = int(np.searchsorted(view.t_s, view.t_s[0] + PLOT_TRACK_SPAN_S, side="right"))
    theta_circle = np.linspace(0, 2 * np.pi, 361)
    t_axis = view.t_s
    handles, labels = [], []
    # Largest constellation first, so the few GPS tracks are drawn over the Starlink ones.
    order = sorted(view.constellations.items(), key=lambda item: -item[1].n_loaded)
    for i, (name, c) in enumerate(order):
        colour = _colour(name, i)
        mask_deg = math.degrees(c.mask_rad)
        z = 2 + 2 * i
        ax_sky.plot(theta_circle, np.full_like(theta_circle, 90 - mask_deg), ls="--", lw=0.8, color=colour, alpha=0.8)
        sats, az, el, _vis = c.dense(nt)
        az, el = az[:, :n_track], el[:, :n_track]
        # Unwrap azimuth so a track crossing North is drawn across it; NaN breaks the line.
        for row in range(sats.size):
            finite = np.isfinite(az[row])
            az[row, finite] = np.unwrap(az[row, finite])
        sep = np.full((sats.size, 1), np.nan)
        ax_sky.plot(np.hstack([az, sep]).ravel(), np.hstack([90 - np.degrees(el), sep]).ravel(),
                    lw=0.5 if c.n_loaded > 100 else 1.0, color=colour, alpha=0.5 if c.n_loaded > 100 else 0.9,
                    zorder=z)
        now = c.t_index == 0
        el0 = np.degrees(c.el_rad[now])
        az0 = c.az_rad[now]
        ax_sky.scatter(az0, 90 - el0, s=9, color=colour, zorder=z + 1, edgecolors="white", linewidths=0.3)
        idx0 = c.sat_index[now]
        for k in _label_rows(az0, el0):
            j = int(idx0[k])
            ax_sky.annotate(short_label(c.names[j], int(c.norad_ids[j])), (az0[k], 90 - el0[k]),
                            xytext=(2.5, 2.5), textcoords="offset points", fontsize=4.8, color=colour,
                            zorder=z + 1)
        handles.append(ax_cnt.step(t_axis, c.count, where="post", color=colour, lw=1.2)[0])
        shown = "" if el0.size <= MAX_LABELS else ", highest labelled"
        key = ", SL-n = STARLINK-n" if name == "starlink" else ""
        labels.append(f"{name}: mask {mask_deg:g}° (dashed), {int(c.count[0])} visible at start{shown}{key}")
        k = int(np.argmin(c.count))
        # the minimum is pointed at from below, so no marker sits on the line
        ax_cnt.annotate(f"min {int(c.count[k])}", (t_axis[k], c.count[k]), textcoords="offset points",
                        xytext=(0, -11), ha="center", va="top", color=colour, fontsize=6,
                        arrowprops={"arrowstyle": "-|>", "color": colour, "lw": 0.7, "shrinkA": 0, "shrinkB": 1.5})
    track_span = view.t_s[n_track - 1] - view.t_s[0]
    ax_sky.set_title(f"sky tracks over the first {track_span:.0f} s, dots at start\n"
                     "elevation 90° at the centre, 0° at the rim", pad=10)
    ax_cnt.axhline(4, color="grey", lw=0.7, ls=":")
    ax_cnt.text(t_axis[-1], 4, "4 needed for a fix ", va="top", ha="right", fontsize=6, color="grey")
    ax_cnt.set_xlabel("time since start [s]")
    ax_cnt.set_ylabel("visible satellites [-]")
    top = max(int(c.count.max()) for c in view.constellations.values()) if view.constellations else 4
    ax_cnt.set_ylim(-0.3 * max(top, 4), 1.12 * max(top, 4))
    ax_cnt.set_yticks([v for v in ax_cnt.get_yticks() if 0 <= v <= 1.12 * max(top, 4)])  # room for the minima
    lat, lon = math.degrees(view.site.lat_rad), math.degrees(view.site.lon_rad)
    ax_cnt.set_title(f"visible at {lat:.4f}°, {lon:.4f}°, {view.site.h_m:g} m from "
                     f"{view.epoch_utc:%Y-%m-%d %H:%M:%S} UTC", fontsize=6.5)
    ps.legend_below(fig, handles, labels, ncol=1, bottom=-0.07)
    ps.save(fig, path)
