"""The study figure: heat maps (two varied fields) or lines (one), position RMSE and sqrt(PCRB).

Two varied fields: per mode a row of three heat maps, time-averaged and final-epoch position
RMSE, each cell annotated "RMSE / sqrt(PCRB)", and the NEES (consistency, log colour bar
with plain ticks). Where the paper reports a band for the mode (LEO(alpha)+IMU 6-9 m, its
static run without outages) the position maps carry its 6 m and 9 m contours. One field:
RMSE (solid) and sqrt(PCRB) (dashed), time-averaged (circles) and final epoch (squares),
against the value, with the paper's band shaded, and the NEES with its 95 % band beside
it. Drawn through `plot_style` like every other figure: units in brackets, one legend
below the panels.
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from leonav_runtime.common import plot_style as ps
from leonav_runtime.sweep.paper_values import PAPER_FINDINGS
from leonav_runtime.study.spec import value_label

HEAT_KEYS = ("position_rmse_m", "position_sqrt_pcrb_m", "position_final_rmse_m", "position_final_sqrt_pcrb_m",
             "nees_mean", "nees_lo", "nees_hi")


def _numeric(values: tuple[Any, ...]) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def _label(text: str) -> str:
    """An axis label with its unit in brackets: "sigma_alpha (Hz/s)" -> "sigma_alpha [Hz/s]"."""
    return re.sub(r"\(([^()]*)\)\s*$", r"[\1]", text.strip())


def _ticks(values: tuple[Any, ...]) -> list[str]:
    return [value_label(v) for v in values]


def paper_band(study, mode: str) -> tuple[float, float] | None:
    """The paper's position band (m) that applies to `mode` in this study, if any: LEO(alpha)+IMU
    on static cells without GPS outages (the paper's 6-9 m is for its static simulation)."""
    if mode != "leo-alpha+imu":
        return None
    static = all(c.scenario.trajectory["kind"] == "static" and not c.scenario.gps["outages"] for c in study.cells)
    return PAPER_FINDINGS["leo_alpha_position_m"] if static else None


def _heat(ax, grid: np.ndarray, bound: np.ndarray | None, study, title: str, norm, cmap: str):
    a0, a1 = study.axes
    im = ax.imshow(grid, origin="lower", aspect="auto", cmap=cmap, norm=norm)
    for i in range(grid.shape[0]):
        for j in range(grid.shape[1]):
            text = f"{grid[i, j]:.1f}" + ("" if bound is None else f"\n/{bound[i, j]:.1f}")
            level = norm(grid[i, j])
            dark = level > 0.5 if cmap == "viridis_r" else abs(level - 0.5) > 0.3
            ax.text(j, i, text, ha="center", va="center", fontsize=5, color="white" if dark else "black")
    ax.set_xticks(range(len(a1.values)), _ticks(a1.values))
    ax.set_yticks(range(len(a0.values)), _ticks(a0.values))
    ax.set_xlabel(_label(a1.label))
    ax.set_ylabel(_label(a0.label))
    ax.set_title(title)
    ax.grid(False)
    return im


def _band_contours(ax, grid: np.ndarray, band: tuple[float, float]) -> bool:
    """The band's low and high contours on a heat map; whether any was drawn."""
    if min(grid.shape) < 2 or not np.all(np.isfinite(grid)) or not (grid.min() < band[1] and grid.max() > band[0]):
        return False
    ax.contour(np.arange(grid.shape[1]), np.arange(grid.shape[0]), grid, levels=list(band), colors="red",
               linewidths=1.2, linestyles=["--", "-"])
    return True


def _two_fields(plt, study, rows: dict):
    import matplotlib

    modes = study.modes
    shape = tuple(len(a.values) for a in study.axes)
    fig, axes = plt.subplots(len(modes), 3, figsize=(2.8 * ps.COLUMN_WIDTH_IN, 3.0 * len(modes)), squeeze=False,
                             gridspec_kw={"hspace": 0.75, "wspace": 0.45})
    for r, mode in enumerate(modes):
        g = {k: np.full(shape, np.nan) for k in HEAT_KEYS}
        for cell in study.cells:
            for k in g:
                g[k][cell.index] = rows[(cell.index, mode)][k]
        vals = np.concatenate([g["position_rmse_m"].ravel(), g["position_final_rmse_m"].ravel()])
        norm = matplotlib.colors.Normalize(float(np.nanmin(vals)), float(np.nanmax(vals)))
        band = paper_band(study, mode)
        drawn = False
        for c, (key, bound, what) in enumerate((("position_rmse_m", "position_sqrt_pcrb_m", "time-averaged"),
                                                ("position_final_rmse_m", "position_final_sqrt_pcrb_m",
                                                 "final-epoch"))):
            im = _heat(axes[r, c], g[key], g[bound], study, f"{mode}: {what}\nposition RMSE / sqrt(PCRB) [m]",
                       norm, "viridis_r")
            if band:
                drawn |= _band_contours(axes[r, c], g[key], band)
        fig.colorbar(im, ax=axes[r, :2].tolist(), shrink=0.9, label="position RMSE [m]")
        if drawn:
            axes[r, 0].annotate(f"red: the paper's {band[0]:g} m (dashed) and {band[1]:g} m (solid) contours",
                                (0, -0.3), xycoords="axes fraction", fontsize=6, va="top", color="red")
        dof = 9.0   # the 9D error: NEES averages 9 when the filter is consistent
        span = max(float(np.nanmax(g["nees_mean"])) / dof, dof / float(np.nanmin(g["nees_mean"])), 2.0)
        im = _heat(axes[r, 2], g["nees_mean"], None, study,
                   f"{mode}: NEES [-]\n9 if consistent, 95 % band {np.nanmin(g['nees_lo']):.1f}-"
                   f"{np.nanmax(g['nees_hi']):.1f}", matplotlib.colors.LogNorm(dof / span, dof * span), "RdBu_r")
        cbar = fig.colorbar(im, ax=axes[r, 2], shrink=0.9, label="NEES [-]")
        ps.plain_log_ticks(cbar.ax.yaxis, subs=(1.0, 2.0, 5.0) if span < 10 else (1.0,))   # <= 2 decades: 1-2-5
    return fig


def _one_field(plt, study, rows: dict):
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    (axis,) = study.axes
    numeric = _numeric(axis.values)
    x = np.array(axis.values, float) if numeric else np.arange(len(axis.values))
    fig, (ax, ax_n) = plt.subplots(1, 2, figsize=(2 * ps.COLUMN_WIDTH_IN, 2.6), gridspec_kw={"width_ratios": [3, 2]})
    styles = ps.series_styles(study.modes)
    handles, labels = [], []
    for mode in study.modes:
        st = styles[mode]
        get = lambda k: [rows[(c.index, mode)][k] for c in study.cells]  # noqa: E731
        ax.plot(x, get("position_rmse_m"), "o-", color=st["color"])
        ax.plot(x, get("position_sqrt_pcrb_m"), "o--", color=st["color"], alpha=0.7)
        ax.plot(x, get("position_final_rmse_m"), "s-", color=st["color"], mfc="none")
        ax.plot(x, get("position_final_sqrt_pcrb_m"), "s:", color=st["color"], mfc="none")
        ax_n.plot(x, get("nees_mean"), "o-", color=st["color"])
        ax_n.fill_between(x, get("nees_lo"), get("nees_hi"), color=st["color"], alpha=0.15)
        handles.append(Line2D([], [], color=st["color"], lw=3))
        labels.append(mode)
        band = paper_band(study, mode)
        if band:
            ax.axhspan(*band, color=st["color"], alpha=0.12, lw=0)
            handles.append(Patch(color=st["color"], alpha=0.25))
            labels.append(f"paper: {mode} {band[0]:g}-{band[1]:g} m")
    handles += [Line2D([], [], color="0.3", ls="-", marker="o"), Line2D([], [], color="0.3", ls="--", marker="o"),
                Line2D([], [], color="0.3", ls="-", marker="s", mfc="none"),
                Line2D([], [], color="0.3", ls=":", marker="s", mfc="none")]
    labels += ["RMSE, time-averaged", "sqrt(PCRB), time-averaged", "RMSE, final epoch", "sqrt(PCRB), final epoch"]
    for a in (ax, ax_n):
        if numeric and x.min() > 0 and x.max() / x.min() >= 20:
            ps.plain_log_axis(a, "x")
        if not numeric:
            a.set_xticks(x, _ticks(axis.values))
        a.set_xlabel(_label(axis.label))
    ax.set_ylabel("position RMSE, sqrt(PCRB) [m]")
    ps.plain_log_axis(ax_n, "y")
    ax_n.set_ylabel("NEES [-] (shaded: 95 % band)")
    ps.legend_below(fig, handles, labels, ncol=3, bottom=-0.02)
    fig.subplots_adjust(bottom=0.22 + 0.05 * (len(labels) // 3), wspace=0.3)
    return fig


def plot_study(study, rows: dict, path: Path) -> None:
    """Write the study figure to `path` (PNG)."""
    plt = ps.pyplot()
    count_note = f"N = {study.cells[0].count}" if len({c.count for c in study.cells}) == 1 else "N per cell"
    fig = _two_fields(plt, study, rows) if len(study.axes) == 2 else _one_field(plt, study, rows)
    fig.suptitle(f"study {study.name} ({study.trials} trials per cell, {count_note} Starlink satellites)",
                 y=1.0 + 0.06 / len(study.modes) if len(study.axes) == 2 else 1.04)
    ps.save(fig, path)
