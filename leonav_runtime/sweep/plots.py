"""Figures of a sweep, like the paper's: RMSE vs Starlink count with the sqrt(PCRB) and the
paper's reported bands, RMSE vs time, the trajectory with its errors, and the visibility
figure. Sized for the paper's column width (plot_style); one legend under the panels."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator

from leonav_runtime.common import plot_style as ps
from leonav_runtime.sweep.paper_values import PAPER_FINDINGS
from leonav_runtime.scenarios.load import mode_of

# block -> (axis label, unit, scale from SI)
BLOCKS = {"position": ("position RMSE", "m", 1.0), "velocity": ("velocity RMSE", "m/s", 1.0),
          "attitude": ("attitude RMSE", "deg", 180.0 / math.pi)}


def _uses_starlink(mode: str) -> bool:
    return mode_of(mode).uses("starlink")


def _paper_bands(scn) -> list[tuple[str, float, float, object]]:
    """(label, low m, high m, colour) of the paper's reported position bands that apply to `scn`."""
    if scn.gps["outages"] or scn.trajectory["kind"] != "static":
        return []  # the paper's 1-2 m / 6-9 m are for its static run
    styles = ps.series_styles(scn.modes)
    out = []
    if any(mode_of(m).uses("gps") for m in scn.modes):
        lo, hi = PAPER_FINDINGS["gps_aided_position_m"]
        out.append((f"paper: GPS-aided {lo:g}-{hi:g} m", lo, hi, "0.55"))
    if "leo-alpha+imu" in scn.modes:
        lo, hi = PAPER_FINDINGS["leo_alpha_position_m"]
        out.append((f"paper: LEO(α)+IMU {lo:g}-{hi:g} m", lo, hi, styles["leo-alpha+imu"]["color"]))
    return out


def _mode_handles(modes, styles):
    return [Line2D([], [], color=styles[m]["color"], marker=styles[m]["marker"]) for m in modes], list(modes)


def plot_rmse_vs_count(scn, res, path: Path) -> None:
    plt = ps.pyplot()
    counts = scn.starlink["counts"]
    styles = ps.series_styles(scn.modes)
    fig, axes = plt.subplots(3, 1, figsize=(ps.COLUMN_WIDTH_IN, 6.4), sharex=True)
    n = len(scn.modes)
    # a small horizontal offset per mode so markers at the same count do not hide each other
    span = (max(counts) - min(counts)) or 4.0
    bands = _paper_bands(scn)
    for ax, (block, (label, unit, scale)) in zip(axes, BLOCKS.items()):
        for i, mode in enumerate(scn.modes):
            st = styles[mode]
            x = np.asarray(counts, float) + (i - (n - 1) / 2) * 0.012 * span
            rmse = [scale * res.summaries[(mode, c)][block]["rmse"] for c in counts]
            bound = [scale * res.summaries[(mode, c)][block]["pcrb"] for c in counts]
            ax.plot(x, rmse, color=st["color"], marker=st["marker"], linestyle="-", ms=4)
            # bound: a dashed line plus a bar marker, visible even with a single count
            ax.plot(x, bound, color=st["color"], linestyle=(0, (2, 2)), lw=0.9, marker="_", ms=9, mew=1.4)
        if block == "position":
            for text, lo, hi, colour in bands:
                ax.axhspan(lo, hi, color=colour, alpha=0.18, lw=0, zorder=0)
        ps.plain_log_axis(ax)
        ax.margins(y=0.1)
        ax.set_ylabel(f"{label} [{unit}]")
    if len(counts) == 1:
        axes[-1].set_xlim(counts[0] - 1, counts[0] + 1)
        axes[-1].set_xticks(counts)
    axes[-1].set_xlabel("Starlink satellites [-]")
    handles, labels = _mode_handles(scn.modes, styles)
    handles += [Line2D([], [], color="k", marker="o", linestyle="-", ms=4),
                Line2D([], [], color="k", linestyle=(0, (2, 2)), marker="_", ms=9, mew=1.4)]
    labels += ["RMSE", "sqrt(PCRB)"]
    for text, _lo, _hi, colour in bands:
        handles.append(Patch(color=colour, alpha=0.3, lw=0))
        labels.append(text)
    fig.suptitle(f"{scn.name}: RMSE vs Starlink count ({scn.trials} trials/point)", y=0.99)
    fig.tight_layout()
    ps.legend_below(fig, handles, labels, ncol=2, bottom=-0.02 - 0.022 * math.ceil(len(labels) / 2))
    ps.save(fig, path)


def plot_rmse_vs_time(scn, res, path: Path) -> None:
    plt = ps.pyplot()
    count = scn.starlink["counts"][-1]
    styles = ps.series_styles(scn.modes)
    fig, axes = plt.subplots(3, 1, figsize=(ps.COLUMN_WIDTH_IN, 6.4), sharex=True)
    for ax, (block, (label, unit, scale)) in zip(axes, BLOCKS.items()):
        for mode in scn.modes:
            s = res.summaries[(mode, count)][block]
            st = styles[mode]
            ax.plot(res.t_eval, scale * s["rmse_t"], color=st["color"], marker=st["marker"], ms=3.5,
                    markevery=max(1, res.t_eval.size // 8))
            ax.plot(res.t_eval, scale * s["pcrb_t"], color=st["color"], linestyle=(0, (2, 2)), lw=0.8, alpha=0.8)
        ps.shade_outages(ax, scn.gps["outages"], label=False)
        ax.set_ylabel(f"{label} [{unit}]")
        ps.plain_log_axis(ax)
    axes[-1].set_xlabel("time since start [s]")
    handles, labels = _mode_handles(scn.modes, styles)
    handles += [Line2D([], [], color="k"), Line2D([], [], color="k", linestyle=(0, (2, 2)), lw=0.8)]
    labels += ["RMSE", "sqrt(PCRB)"]
    if scn.gps["outages"]:
        handles.append(Patch(color="0.85"))
        labels.append("GPS outage")
    fig.suptitle(f"{scn.name}: RMSE vs time at {count} Starlink satellites", y=0.99)
    fig.tight_layout()
    ps.legend_below(fig, handles, labels, ncol=2, bottom=-0.02 - 0.022 * math.ceil(len(labels) / 2))
    ps.save(fig, path)


STATIC_SPAN_M = 1.0  # a truth track within this of its start is drawn as one point


def _is_static(p_enu: np.ndarray) -> bool:
    """True when the truth track never leaves STATIC_SPAN_M (m) of its first point."""
    return bool(np.max(np.linalg.norm(p_enu - p_enu[:1], axis=1)) < STATIC_SPAN_M)


def plot_trajectories(scn, res, path: Path) -> None:
    """Plan view (truth, trial-0 estimates, start marker) and the horizontal / vertical error
    of trial 0 vs time, where errors of a few metres are visible on a km-long track."""
    plt = ps.pyplot()
    styles = ps.series_styles(scn.modes)
    fig, (ax2, axh, axv) = plt.subplots(3, 1, figsize=(ps.COLUMN_WIDTH_IN, 7.0),
                                        gridspec_kw={"height_ratios": [2.2, 1, 1]})
    gt = res.truth_p_enu
    t = res.t_eval
    ax2.plot(gt[:, 0], gt[:, 1], "k-", lw=2.2, alpha=0.6, zorder=1)
    for a, b in scn.gps["outages"]:  # the stretch driven without GPS, as a wide grey band
        sel = (t >= a) & (t <= b)
        ax2.plot(gt[sel, 0], gt[sel, 1], color="0.75", lw=7, solid_capstyle="butt", zorder=0)
    for mode, p in res.trajectories.items():
        st = styles[mode]
        # the path starts at the first output sample: the filter's initial estimate is not
        # on the output grid, so no jump from it is drawn as motion
        ax2.plot(p[:, 0], p[:, 1], color=st["color"], linestyle=st["linestyle"], lw=0.9, zorder=2)
        # where the estimate starts (the initial error, tens of metres) is marked, not guessed
        ax2.plot(p[0, 0], p[0, 1], marker="o", ms=5, mfc="none", mec=st["color"], linestyle="", zorder=3)
        err = p - gt[: p.shape[0]]
        axh.plot(t[: p.shape[0]], np.hypot(err[:, 0], err[:, 1]), color=st["color"], linestyle=st["linestyle"])
        axv.plot(t[: p.shape[0]], err[:, 2], color=st["color"], linestyle=st["linestyle"])
    static = _is_static(gt)
    if static:  # start and end markers would hide each other: one marker says both
        ax2.plot(gt[0, 0], gt[0, 1], "k*", ms=10, zorder=4)
    else:
        ax2.plot(gt[-1, 0], gt[-1, 1], "ks", ms=6, zorder=3, mfc="white")
        ax2.plot(gt[0, 0], gt[0, 1], "k^", ms=7, zorder=4)
    ax2.set_xlabel("East [m]")
    ax2.set_ylabel("North [m]")
    ax2.set_aspect("equal", adjustable="datalim")
    ax2.xaxis.set_major_locator(MaxNLocator(5))
    for ax in (axh, axv):
        ps.shade_outages(ax, scn.gps["outages"], label=False)
    axh.set_ylabel("horizontal error [m]")
    axh.set_ylim(bottom=0)
    axv.axhline(0, color="0.4", lw=0.6)
    axv.set_ylabel("up error [m]")
    axv.set_xlabel("time since start [s]")
    axh.sharex(axv)
    if static:
        handles, labels = [Line2D([], [], color="k", marker="*", ms=10, linestyle="")], ["truth (static)"]
    else:
        handles = [Line2D([], [], color="k", lw=2.2, alpha=0.6), Line2D([], [], color="k", marker="^", linestyle=""),
                   Line2D([], [], color="k", marker="s", mfc="white", linestyle="")]
        labels = ["truth", "start", "end"]
    handles.append(Line2D([], [], color="0.3", marker="o", mfc="none", linestyle=""))
    labels.append("first estimate of each mode")
    handles += [Line2D([], [], color=styles[m]["color"], linestyle=styles[m]["linestyle"]) for m in res.trajectories]
    labels += list(res.trajectories)
    if scn.gps["outages"]:
        handles.append(Patch(color="0.85"))
        labels.append("GPS outage")
    fig.suptitle(f"{scn.name}: trial 0 at {scn.starlink['counts'][-1]} Starlink satellites", y=0.99)
    fig.tight_layout()
    ps.legend_below(fig, handles, labels, ncol=2, bottom=-0.02 - 0.02 * math.ceil(len(labels) / 2))
    ps.save(fig, path)


def plot_visibility(scn, path: Path) -> dict:
    """Visible satellites per constellation over the scenario window (the paper's Fig. 2)."""
    from leonav_runtime.simulation import simulate
    from leonav_runtime.sky import view as sky, plot as sky_plot

    elements = simulate.scenario_elements(scn)
    step = 1.0 if scn.duration_s <= 600 else 10.0
    t = np.arange(0.0, scn.duration_s + 1e-9, step)
    masks = {"gps": scn.gps["elevation_mask_rad"], "starlink": scn.starlink["elevation_mask_rad"]}
    view = sky.sky_view(elements, sky.Site(scn.lat_rad, scn.lon_rad, scn.alt_m), scn.epoch_utc, t, masks)
    sky_plot.plot(view, path)
    return {name: {"min": int(c.min()), "max": int(c.max())} for name, c in view.counts().items()}


def plot_all(scn, res, out_dir: Path) -> None:
    out_dir = Path(out_dir)
    plot_rmse_vs_count(scn, res, out_dir / "rmse_vs_count.png")
    plot_rmse_vs_time(scn, res, out_dir / "rmse_vs_time.png")
    plot_trajectories(scn, res, out_dir / "trajectories.png")
    plot_visibility(scn, out_dir / "visibility.png")
