"""Replay plots: error norms vs time per mode, and 2D/3D trajectories (ENU at the origin)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_rmse_vs_time(path: Path, scored: dict, metrics: dict, layout) -> None:
    plt = _pyplot()
    L = layout
    fig, axes = plt.subplots(3, 1, figsize=(9, 8.5), sharex=True)
    blocks = (("position", L.DX_DP_SLICE, 1.0, "m"), ("velocity", L.DX_DV_SLICE, 1.0, "m/s"),
              ("attitude", L.DX_DTHETA_SLICE, 180 / math.pi, "deg"))
    for ax, (name, sl, scale, unit) in zip(axes, blocks):
        for mode, s in scored.items():
            e = np.sqrt(np.sum(s["err"][:, sl] ** 2, axis=1)) * scale
            if np.any(np.isfinite(e)):
                ax.plot(s["t"], e, label=mode)
        ax.set_ylabel(f"{name} error ({unit})")
        ax.grid(True, alpha=0.3)
    if axes[0].get_legend_handles_labels()[0]:
        axes[0].legend(fontsize=8)
    axes[-1].set_xlabel("time since the first IMU sample (s)")
    ref = metrics.get("reference") or "none"
    fig.suptitle(f"Replay of {Path(metrics['session']).name}: error vs time (reference: {ref})", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_trajectories(path: Path, scored: dict, ref, inputs, layout) -> None:
    plt = _pyplot()
    fig = plt.figure(figsize=(13, 5.5))
    ax2 = fig.add_subplot(1, 2, 1)
    ax3 = fig.add_subplot(1, 2, 2, projection="3d")
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
        ax2.plot(p[:, 0], p[:, 1], lw=1.2, label=mode)
        ax3.plot(p[:, 0], p[:, 1], p[:, 2], lw=1.2)
    ax2.set_xlabel("East (m)")
    ax2.set_ylabel("North (m)")
    ax2.axis("equal")
    ax2.grid(True, alpha=0.3)
    ax2.legend(fontsize=8)
    ax3.set_xlabel("East (m)")
    ax3.set_ylabel("North (m)")
    ax3.set_zlabel("Up (m)")
    fig.suptitle("2D and 3D trajectories (ENU at the origin)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
