"""Replay plots: error norms vs time per mode, and 2D/3D trajectories (ENU at the origin)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np


def _pyplot():
    from leonav_runtime.common import plot_style

    return plot_style.pyplot()


def plot_rmse_vs_time(path: Path, scored: dict, metrics: dict, layout) -> None:
    plt = _pyplot()
    L = layout
    from leonav_runtime.common import plot_style as ps

    fig, axes = plt.subplots(3, 1, figsize=(ps.COLUMN_WIDTH_IN, 6.4), sharex=True)
    styles = ps.series_styles(list(scored))
    blocks = (("position", L.DX_DP_SLICE, 1.0, "m"), ("velocity", L.DX_DV_SLICE, 1.0, "m/s"),
              ("attitude", L.DX_DTHETA_SLICE, 180 / math.pi, "deg"))
    for ax, (name, sl, scale, unit) in zip(axes, blocks):
        for mode, s in scored.items():
            e = np.sqrt(np.sum(s["err"][:, sl] ** 2, axis=1)) * scale
            if np.any(np.isfinite(e)):
                ax.plot(s["t"], e, label=mode, color=styles[mode]["color"], linestyle=styles[mode]["linestyle"])
        ax.set_ylabel(f"{name} error [{unit}]")
    axes[-1].set_xlabel("time since the first IMU sample [s]")
    ref = metrics.get("reference") or "none"
    fig.suptitle(f"Replay of {Path(metrics['session']).name}: error vs time\n(reference: {ref})")
    fig.tight_layout()
    handles, labels = axes[0].get_legend_handles_labels()
    if handles:
        ps.legend_below(fig, handles, labels, ncol=2, bottom=-0.06)
    ps.save(fig, path)


def plot_trajectories(path: Path, scored: dict, ref, inputs, layout) -> None:
    from leonav_runtime.common import plot_style as ps

    plt = _pyplot()
    fig = plt.figure(figsize=(ps.COLUMN_WIDTH_IN, 6.6))
    ax2 = fig.add_subplot(2, 1, 1)
    ax3 = fig.add_subplot(2, 1, 2, projection="3d")
    styles = ps.series_styles(list(scored))
    if ref is not None:
        p = ref.p_enu_m
        if ref.rpy_rad is None:
            ax2.scatter(p[:, 0], p[:, 1], s=6, color="0.5", label="GNSS fixes")
            ax3.scatter(p[:, 0], p[:, 1], p[:, 2], s=4, color="0.5")
        else:
            sel = (ref.t >= inputs.imu.t[0] - 0.2) & (ref.t <= inputs.imu.t[-1] + 0.2)
            ax2.plot(p[sel, 0], p[sel, 1], "*-", ms=12, zorder=5, color="k", lw=2.0, label=f"reference ({ref.kind})")
            ax3.plot(p[sel, 0], p[sel, 1], p[sel, 2], "*-", ms=10, color="k", zorder=5)
    if inputs.fixes.t.size and (ref is None or ref.rpy_rad is not None):
        ax2.scatter(inputs.fixes.p_enu_m[:, 0], inputs.fixes.p_enu_m[:, 1], s=5, color="0.7", label="GNSS fixes")
    for mode, s in scored.items():
        p = s["x"][:, layout.X_P_ENU_SLICE]
        st = styles[mode]
        # the path starts after the first filter step: the jump from the initial estimate
        # to the first corrected state is not motion, it is shown as the hollow marker
        ax2.plot(p[1:, 0], p[1:, 1], lw=1.0, label=mode, color=st["color"], linestyle=st["linestyle"])
        ax2.plot(p[0, 0], p[0, 1], marker=st["marker"], mfc="none", color=st["color"], ms=6, linestyle="")
        ax3.plot(p[1:, 0], p[1:, 1], p[1:, 2], lw=1.0, color=st["color"], linestyle=st["linestyle"])
    if scored:
        first = next(iter(scored.values()))["x"][1:, layout.X_P_ENU_SLICE]
        if first.shape[0]:
            ax2.plot(first[0, 0], first[0, 1], "k^", ms=6, label="start (first filter step)", zorder=6)
    ax2.plot([], [], marker="o", mfc="none", color="0.3", linestyle="", label="initial estimate")
    ax2.set_xlabel("East [m]")
    ax2.set_ylabel("North [m]")
    ax2.axis("equal")
    ax3.set_xlabel("East [m]")
    ax3.set_ylabel("North [m]")
    ax3.set_zlabel("Up [m]")
    fig.suptitle("2D and 3D trajectories (ENU at the origin)")
    fig.tight_layout()
    handles, labels = ax2.get_legend_handles_labels()
    ps.legend_below(fig, handles, labels, ncol=2, bottom=-0.13)
    ps.save(fig, path)
