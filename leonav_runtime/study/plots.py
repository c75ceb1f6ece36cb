"""The study figure: heat maps (two varied fields) or lines (one), position RMSE and sqrt(PCRB).

Two varied fields: per mode a row of two heat maps, time-averaged and final-epoch position
RMSE, each cell annotated "RMSE / sqrt(PCRB)", and the NEES (consistency). One field: per mode, RMSE (solid) and
sqrt(PCRB) (dashed), time-averaged (circles) and final epoch (squares), against the value,
and the NEES with its 95 % band beside it.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def _numeric(values: tuple[Any, ...]) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def _ticks(values: tuple[Any, ...]) -> list[str]:
    return [f"{v:g}" if isinstance(v, float) else str(v) for v in values]


def _heat(ax, grid: np.ndarray, bound: np.ndarray | None, study, title: str, vmin: float, vmax: float,
          cmap: str = "viridis_r", log: bool = False):
    a0, a1 = study.axes
    norm = matplotlib.colors.LogNorm(vmin, vmax) if log else matplotlib.colors.Normalize(vmin, vmax)
    im = ax.imshow(grid, origin="lower", aspect="auto", cmap=cmap, norm=norm)
    for i in range(grid.shape[0]):
        for j in range(grid.shape[1]):
            text = f"{grid[i, j]:.1f}" + ("" if bound is None else f"\n/{bound[i, j]:.1f}")
            dark = norm(grid[i, j]) > 0.5 if cmap == "viridis_r" else abs(norm(grid[i, j]) - 0.5) > 0.3
            ax.text(j, i, text, ha="center", va="center", fontsize=7, color="white" if dark else "black")
    ax.set_xticks(range(len(a1.values)), _ticks(a1.values))
    ax.set_yticks(range(len(a0.values)), _ticks(a0.values))
    ax.set_xlabel(a1.label)
    ax.set_ylabel(a0.label)
    ax.set_title(title, fontsize=9)
    return im


def plot_study(study, rows: dict, path: Path) -> None:
    """Write the study figure to `path` (PNG)."""
    modes = study.modes
    count_note = f"N = {study.cells[0].count}" if len({c.count for c in study.cells}) == 1 else "N per cell"
    if len(study.axes) == 2:
        shape = tuple(len(a.values) for a in study.axes)
        fig, axes = plt.subplots(len(modes), 3, figsize=(16, 4.6 * len(modes)), squeeze=False,
                                 gridspec_kw={"hspace": 0.5, "wspace": 0.3})
        for r, mode in enumerate(modes):
            grids = {k: np.full(shape, np.nan) for k in ("position_rmse", "position_pcrb", "position_final_rmse",
                                                          "position_final_pcrb", "nees_mean", "nees_lo", "nees_hi")}
            for cell in study.cells:
                for k in grids:
                    grids[k][cell.index] = rows[(cell.index, mode)][k]
            vals = np.concatenate([grids["position_rmse"].ravel(), grids["position_final_rmse"].ravel()])
            vmin, vmax = float(np.nanmin(vals)), float(np.nanmax(vals))
            _heat(axes[r, 0], grids["position_rmse"], grids["position_pcrb"], study,
                  f"{mode}\ntime-averaged position RMSE / sqrt(PCRB), m", vmin, vmax)
            im = _heat(axes[r, 1], grids["position_final_rmse"], grids["position_final_pcrb"], study,
                       f"{mode}\nfinal-epoch position RMSE / sqrt(PCRB), m", vmin, vmax)
            fig.colorbar(im, ax=axes[r, :2].tolist(), shrink=0.9, label="position RMSE (m)")
            dof = 9.0   # the 9D error: NEES averages 9 when the filter is consistent
            span = max(float(np.nanmax(grids["nees_mean"])) / dof, dof / float(np.nanmin(grids["nees_mean"])), 2.0)
            im = _heat(axes[r, 2], grids["nees_mean"], None, study,
                       f"{mode}\nNEES (9 if consistent; 95 % band {np.nanmin(grids['nees_lo']):.1f}.."
                       f"{np.nanmax(grids['nees_hi']):.1f})", dof / span, dof * span, cmap="RdBu_r", log=True)
            fig.colorbar(im, ax=axes[r, 2], shrink=0.9, label="NEES")
    else:
        (axis,) = study.axes
        numeric = _numeric(axis.values)
        x = np.array(axis.values, float) if numeric else np.arange(len(axis.values))
        fig, (ax, ax_n) = plt.subplots(1, 2, figsize=(13, 5), gridspec_kw={"width_ratios": [3, 2]})
        cmap = plt.get_cmap("tab10")
        for i, mode in enumerate(modes):
            get = lambda k: [rows[(c.index, mode)][k] for c in study.cells]  # noqa: E731
            ax.plot(x, get("position_rmse"), "o-", color=cmap(i), label=f"{mode}: RMSE, time-averaged")
            ax.plot(x, get("position_pcrb"), "o--", color=cmap(i), alpha=0.7, label="sqrt(PCRB), time-averaged")
            ax.plot(x, get("position_final_rmse"), "s-", color=cmap(i), mfc="none", label="RMSE, final epoch")
            ax.plot(x, get("position_final_pcrb"), "s:", color=cmap(i), mfc="none", label="sqrt(PCRB), final epoch")
            ax_n.plot(x, get("nees_mean"), "o-", color=cmap(i), label=mode)
            ax_n.fill_between(x, get("nees_lo"), get("nees_hi"), color=cmap(i), alpha=0.15)
        for a in (ax, ax_n):
            if numeric and x.min() > 0 and x.max() / x.min() >= 20:
                a.set_xscale("log")
            if not numeric:
                a.set_xticks(x, _ticks(axis.values))
            a.set_xlabel(axis.label)
            a.grid(True, which="both", alpha=0.3)
        ax.set_ylabel("position RMSE (m)")
        ax.legend(fontsize=7)
        ax_n.set_yscale("log")
        ax_n.set_ylabel("NEES, mean over trials and time (shaded: 95 % band)")
        ax_n.legend(fontsize=7)
    fig.suptitle(f"study {study.name} ({study.trials} trials per cell, {count_note} Starlink satellites)", y=1.02)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
