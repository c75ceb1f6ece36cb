"""Figures of a sweep, like the paper's: RMSE vs Starlink count with the PCRB dashed,
RMSE vs time, 2D/3D trajectories with ground truth, and the visibility figure."""
from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


UNITS = {"position": ("m", 1.0), "velocity": ("m/s", 1.0), "attitude": ("deg", 180.0 / math.pi)}


def _colours(modes):
    cmap = plt.get_cmap("tab10")
    return {m: cmap(i % 10) for i, m in enumerate(modes)}


def plot_rmse_vs_count(scn, res, path: Path) -> None:
    counts = scn.starlink["counts"]
    colours = _colours(scn.modes)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5))
    for ax, (block, (unit, scale)) in zip(axes, UNITS.items()):
        for mode in scn.modes:
            rmse = [scale * res.summaries[(mode, c)][block]["rmse"] for c in counts]
            bound = [scale * res.summaries[(mode, c)][block]["pcrb"] for c in counts]
            ax.plot(counts, rmse, "o-", color=colours[mode], label=mode)
            ax.plot(counts, bound, "--", color=colours[mode], alpha=0.8)
        ax.set_yscale("log")
        ax.set_xlabel("number of Starlink satellites")
        ax.set_ylabel(f"{block} RMSE ({unit})")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=8, title="solid: RMSE, dashed: sqrt(PCRB)", title_fontsize=8)
    fig.suptitle(f"{scn.name}: RMSE vs Starlink satellites ({scn.trials} trials per point)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_rmse_vs_time(scn, res, path: Path) -> None:
    count = scn.starlink["counts"][-1]
    colours = _colours(scn.modes)
    fig, axes = plt.subplots(3, 1, figsize=(10, 9), sharex=True)
    for ax, (block, (unit, scale)) in zip(axes, UNITS.items()):
        for mode in scn.modes:
            s = res.summaries[(mode, count)][block]
            ax.plot(res.t_eval, scale * s["rmse_t"], color=colours[mode], label=mode)
            ax.plot(res.t_eval, scale * s["pcrb_t"], "--", color=colours[mode], alpha=0.7)
        for a, b in scn.gps["outages"]:
            ax.axvspan(a, b, color="0.85", zorder=0, label="GPS outage" if block == "position" else None)
        ax.set_ylabel(f"{block} RMSE ({unit})")
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=8, ncol=2)
    axes[-1].set_xlabel("time since start (s)")
    fig.suptitle(f"{scn.name}: RMSE vs time at {count} Starlink satellites (dashed: sqrt(PCRB))")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_trajectories(scn, res, path: Path) -> None:
    colours = _colours(scn.modes)
    fig = plt.figure(figsize=(14, 6))
    ax2 = fig.add_subplot(1, 2, 1)
    ax3 = fig.add_subplot(1, 2, 2, projection="3d")
    gt = res.truth_p_enu
    ax2.plot(gt[:, 0], gt[:, 1], "k-", lw=2, label="GT")
    ax3.plot(gt[:, 0], gt[:, 1], gt[:, 2], "k-", lw=2, label="GT")
    for mode, p in res.trajectories.items():
        ax2.plot(p[:, 0], p[:, 1], ".-", ms=2, lw=0.8, color=colours[mode], label=mode)
        ax3.plot(p[:, 0], p[:, 1], p[:, 2], lw=0.8, color=colours[mode], label=mode)
    ax2.plot(gt[0, 0], gt[0, 1], "ks", ms=6)
    ax2.set_xlabel("East (m)")
    ax2.set_ylabel("North (m)")
    ax2.set_aspect("equal", adjustable="datalim")
    ax2.grid(True, alpha=0.3)
    ax2.legend(fontsize=8)
    ax3.set_xlabel("East (m)")
    ax3.set_ylabel("North (m)")
    ax3.set_zlabel("Up (m)")
    fig.suptitle(f"{scn.name}: trajectories of trial 0 at {scn.starlink['counts'][-1]} Starlink satellites "
                 "(GT = ground truth)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_visibility(scn, path: Path) -> dict:
    """Visible satellites per constellation over the scenario window (the paper's Fig. 2)."""
    from leonav_runtime import simulate, sky, sky_plot

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

