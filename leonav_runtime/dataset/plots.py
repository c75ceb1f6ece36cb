"""Figures of a dataset run: error vs time with the outages shaded, CDF, trajectory on the reference."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from leonav_runtime.dataset.scoring import cdf
from leonav_runtime.dataset.spec import MODES

GPS_STYLE = {"color": "0.55", "ls": "-", "lw": 0.8}
_STYLES = [{"color": "C0", "ls": "-", "lw": 1.4}, {"color": "C2", "ls": "--", "lw": 1.2},
           {"color": "C3", "ls": ":", "lw": 1.6}]


def style(mode: str) -> dict:
    """Colour, line style and width of a mode, the same in every figure; modes whose lines lie on
    top of each other (e.g. +zupt when the vehicle never stops) stay visible by their styles."""
    return dict(_STYLES[MODES.index(mode)]) if mode in MODES else {"color": "C4", "ls": "-", "lw": 1.0}


def _pyplot():
    from leonav_runtime.common import plot_style

    return plot_style.pyplot()


def _finish(fig, ax, path: Path) -> Path:
    """Grid, legend, layout; saved at the shared DPI and closed."""
    from leonav_runtime.common import plot_style

    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    plot_style.save(fig, path)
    return path


def error_vs_time(path: Path, series: dict, gps: dict, outage_series: dict, length_s: float, title: str) -> Path:
    """Top: horizontal error per mode and GPS alone at the reference epochs (all fixes). Middle:
    every mode's outage runs, each over its own outage (shaded: the only panel where fixes were
    removed), and hold-last-fix. Bottom: yaw error (all fixes)."""
    plt = _pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(10, 9), sharex=True)
    h = lambda e: np.hypot(e[:, 0], e[:, 1])  # noqa: E731
    axes[0].plot(gps["t"], h(gps["err_enu"]), **GPS_STYLE, label="GPS alone (hold last fix)")
    for mode, s in series.items():
        axes[0].plot(s["t"], h(s["err_enu"]), **style(mode), label=mode)
    axes[0].set_ylabel("horizontal error [m]")
    axes[0].legend(fontsize=8, loc="upper right")
    for m, (mode, runs) in enumerate(outage_series.items()):
        for k, (start, s) in enumerate(runs.items()):
            sel = (s["t"] >= start - 5) & (s["t"] <= start + length_s + 5)
            axes[1].plot(s["t"][sel], h(s["err_enu"][sel]), **style(mode),
                         label=f"{mode}, fixes removed" if k == 0 else None)
            if m == 0:      # the same for every mode
                hold = gps["hold_outage"][start]
                axes[1].plot(hold["t"], hold["err_h"], color="0.3", ls="-.", lw=0.9,
                             label="hold last fix" if k == 0 else None)
    for start in next(iter(outage_series.values()), {}):
        axes[1].axvspan(start, start + length_s, color="C1", alpha=0.15, lw=0)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[1].set_ylabel("horizontal error in outages [m]")
    if outage_series:
        axes[1].legend(fontsize=8, loc="upper left")
    else:  # run without outages (--no-outages): say so rather than leave a blank panel unexplained
        axes[1].text(0.5, 0.5, "no outage runs (--no-outages)", transform=axes[1].transAxes, ha="center",
                     va="center", color="0.4")
    for mode, s in series.items():
        axes[2].plot(s["t"], np.degrees(s["yaw_err_rad"]), **style(mode), label=mode)
    axes[2].set_ylabel("yaw error [deg]")
    axes[2].set_ylim(-30, 30)
    axes[2].set_xlabel(f"time since the first GNSS fix [s]; middle panel shaded: the {length_s:g} s GPS outages, "
                       "one run each")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    from leonav_runtime.common import plot_style

    plot_style.save(fig, path)
    return path


def error_cdf(path: Path, series: dict, gps: dict, title: str = "") -> Path:
    """Cumulative distribution of the horizontal error at the reference epochs, per mode and GPS alone."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    v, c = cdf(np.hypot(gps["err_enu"][:, 0], gps["err_enu"][:, 1]))
    ax.plot(v, c, **GPS_STYLE, label="GPS alone (hold last fix)")
    for mode, s in series.items():
        v, c = cdf(np.hypot(s["err_enu"][:, 0], s["err_enu"][:, 1]))
        ax.plot(v, c, **style(mode), label=mode)
    ax.set_xlabel("horizontal error [m]")
    ax.set_ylabel("fraction of reference epochs")
    ax.set_title(title or "horizontal error CDF at the reference epochs", fontsize=10)
    return _finish(fig, ax, path)


def trajectory_on_reference(path: Path, ref_enu: np.ndarray, fixes_enu: np.ndarray, tracks: dict,
                            title: str = "") -> Path:
    """Each mode's track (IMU point, ENU m) over the reference and the GNSS fixes (antenna)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 7))
    ax.plot(fixes_enu[:, 0], fixes_enu[:, 1], ".", ms=1, color="0.7", label="GNSS fixes (antenna)")
    ax.plot(ref_enu[:, 0], ref_enu[:, 1], "k-", lw=2.2, alpha=0.6, label="reference")
    for mode, p in tracks.items():
        ax.plot(p[:, 0], p[:, 1], **style(mode), label=mode)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("East [m]")
    ax.set_ylabel("North [m]")
    ax.set_title(title or "trajectories on the reference", fontsize=10)
    return _finish(fig, ax, path)


def fmt(v, digits: int = 3) -> str:
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.{digits}f}"
