"""Figures and tables of the observability analysis."""
from __future__ import annotations

import math
import textwrap
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from leonav_runtime.observability.naming import *  # noqa: F401,F403

# --- figures -----------------------------------------------------------------------------------

def _pyplot():
    from leonav_runtime.common import plot_style

    return plot_style.pyplot(style=False)   # matplotlib's default look; a notebook keeps its backend


def plot_singular_values(runs: Sequence[dict], path, title: str = "") -> Path:
    """Singular values of the scaled current-state information vs time, one panel per mode.

    runs: `scenario_run` results. A singular value s means the measurements so far give the
    information of a prior of sigma = (unit) / s along that direction (1 = the prior's).
    """
    plt = _pyplot()
    n = max(len(runs), 1)
    cols = min(n, 3)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 3.8 * rows), squeeze=False, sharey=True)
    lows = []
    for ax, run in zip(axes.flat, runs):
        raw = run["singular_values"]
        floor = REL_TOL * raw[:, :1]  # numerically zero below this: not drawn
        sv = np.where(raw > floor, raw, np.nan)
        if np.any(np.isfinite(sv)):
            lows.append(np.nanmin(sv))
        ax.semilogy(run["t_s"], sv, lw=1)
        ax.axhline(1.0, color="k", ls="--", lw=0.8)
        ax.set_title(f"{run['mode']} (rank {int(run['rank'][-1])}/{sv.shape[1]} at the end)", fontsize=9)
        ax.set_xlabel("time since start [s]")
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes[:, 0]:
        ax.set_ylabel("singular value [prior units]")
    if lows:
        axes[0, 0].set_ylim(bottom=max(min(lows) / 3, 1e-30))
    for ax in list(axes.flat)[len(runs):]:
        ax.axis("off")
    fig.suptitle((title or "information along the run: singular values of R Phi^-1 S")
                 + f"\n(dashed: the prior's information; values below {REL_TOL:g} x the largest are numerically 0, "
                   "not drawn)",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_index(mode: str, components: Sequence[str], by_motion: Mapping[str, np.ndarray], path,
               run_index: np.ndarray | None = None, run_label: str = "scenario") -> Path:
    """Per-component observability index of one mode: one bar per motion class (structural
    analysis, unit prior) and, when given, the index at the end of a scenario run (prior P0)."""
    plt = _pyplot()
    series = dict(by_motion)
    if run_index is not None:
        series[run_label] = np.asarray(run_index)
    x = np.arange(len(components))
    width = 0.8 / max(len(series), 1)
    fig, ax = plt.subplots(figsize=(max(8.0, 0.55 * len(components)), 3.8))
    for i, (label, idx) in enumerate(series.items()):
        ax.bar(x + (i - (len(series) - 1) / 2) * width, np.clip(idx, 0, 1), width, label=label)
    ax.set_xticks(x)
    ax.set_xticklabels(components, rotation=60, ha="right", fontsize=8)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("index: 1 - posterior/prior variance [-]")
    ax.set_title(f"{mode}: observability index per state (0 = no information)", fontsize=10)
    ax.legend(fontsize=7, ncol=min(len(series), 5))
    ax.grid(True, axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


# --- tables ------------------------------------------------------------------------------------

STRUCTURAL_HEADER = ("mode", "motion", "rank", "n_states", "weak", "nullity", "steps_to_saturate", "gap",
                     "gap_clear", "draws_agree", "unobservable_directions", "weak_directions",
                     "weakest_observable", "weakest_sigma", "weakest_sigma_unit")


def structural_rows(summaries: Sequence[dict]) -> list[list]:
    """CSV rows (STRUCTURAL_HEADER) of structural-analysis summaries (`CaseResult.summary()`)."""
    rows = []
    for s in summaries:
        w = s.get("weakest_observable") or {}
        rows.append([s["mode"], s["motion"], s["rank"], s["n_states"], s["weak"], s["nullity"],
                     s["steps_to_saturate"], s["gap"], s["gap_clear"], s["draws_agree"],
                     " | ".join(d["text"] for d in s["unobservable_directions"]),
                     " | ".join(f"{d['text']} (sigma {d['sigma']:.2g} {d['sigma_unit']})" for d in s["weak_directions"]),
                     w.get("text", ""), w.get("sigma", math.nan), w.get("sigma_unit", "")])
    return rows


def format_structural_table(summaries: Sequence[dict]) -> str:
    """The mode x motion table as printed by `leonav observability`, with its legend.

    Unobservable directions are named by their major terms (full combinations in the CSV/JSON).
    """
    from leonav_runtime.common.text_table import text_table

    rows = []
    for s in summaries:
        gap = "inf" if not math.isfinite(s["gap"]) else f"{s['gap']:.0e}"
        flags = ("" if s["gap_clear"] else " (gap not clear)") + ("" if s["draws_agree"] else " (draws disagree)")
        null = "; ".join(d["label"] for d in s["unobservable_directions"]) or "none"
        weak = "; ".join(f"{d['label']}: sigma {d['sigma']:.0e} {d['sigma_unit']}" for d in s["weak_directions"])
        rows.append([s["mode"], s["motion"], f"{s['rank']}/{s['n_states']}", s["weak"] or "-",
                     s["steps_to_saturate"], gap, f"{null}{' [' + weak + ']' if weak else ''}{flags}"])
    lines = text_table(["mode", "motion", "rank", "weak", "steps", "gap",
                        "unobservable directions (null space)  [weak directions]"], rows, "llrrrrl")
    return "\n".join(lines + [textwrap.fill(STRUCTURAL_LEGEND, 110)])


STRUCTURAL_LEGEND = (
    "rank: observable directions of the error state / its size (numerical rank of the observability matrix); "
    "weak: of those, directions observable only weakly (singular value below the weak threshold above, relative to the largest); "
    "steps: measurement epochs until the rank stops growing; gap: sigma_r / sigma_(r+1), the margin between "
    "the last observable and the first unobservable direction (inf: nothing unobservable left)")


def format_time_to_target(runs: Sequence[dict]) -> str:
    """Per mode and component: seconds until the measurements alone give sigma <= target ('-': never)."""
    if not runs:
        return ""
    names = runs[0]["components"]
    width = max(6, max(len(n) for n in names) + 1)
    lines = [f"{'mode':22s} " + "".join(f"{n:>{width}s}" for n in names)]
    for r in runs:
        cells = "".join(f"{(f'{v:.0f}' if math.isfinite(v) else '-'):>{width}s}" for v in r["time_to_target_s"])
        lines.append(f"{r['mode']:22s} {cells}")
    return "\n".join(lines)

