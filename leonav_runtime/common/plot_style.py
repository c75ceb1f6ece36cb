"""Shared figure style: sized for a paper column (~3.5 in), plain log tick labels, one
legend outside the panels, and a distinct colour + marker + line style per series.

Every figure module draws through `pyplot()` and these helpers so the PNGs look alike and
stay readable when printed at the paper's single-column width.
"""
from __future__ import annotations

from typing import Iterable, Sequence

COLUMN_WIDTH_IN = 3.5          # the paper's single column
DPI = 200                      # 3.5 in -> 700 px: sharp at column width, small files
FONT_PT = 7.5                  # readable at 100 % of the column width

MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
LINESTYLES = ("-", (0, (5, 1.5)), (0, (1, 1)), (0, (4, 1, 1, 1)), (0, (6, 1, 1, 1, 1, 1)), (0, (2, 1)))


STYLE = {
    "font.size": FONT_PT, "axes.titlesize": FONT_PT + 0.5, "axes.labelsize": FONT_PT,
    "xtick.labelsize": FONT_PT - 0.5, "ytick.labelsize": FONT_PT - 0.5, "legend.fontsize": FONT_PT - 0.5,
    "figure.titlesize": FONT_PT + 1, "lines.linewidth": 1.1, "lines.markersize": 4.0,
    "axes.grid": True, "grid.alpha": 0.3, "savefig.dpi": DPI,
}


_BACKEND_CHOSEN_HERE = False  # leonav selected Agg (the command line), not the user's session


def pyplot(style: bool = True):
    """matplotlib.pyplot for leonav's figure files.

    On the command line (pyplot not imported yet) it selects the headless Agg backend and, with
    `style`, the shared style. Inside a user's session that already uses pyplot (a notebook, a
    script with its own figures) the user's backend and rcParams are left as they are: switching
    to Agg there would stop their inline figures, and the style would change their own plots.
    The figure files are saved at DPI either way (`save`). Every figure module goes through
    here (`style=False` for figures drawn in matplotlib's default look).
    """
    import sys

    import matplotlib

    global _BACKEND_CHOSEN_HERE
    if "matplotlib.pyplot" not in sys.modules:
        matplotlib.use("Agg")
        _BACKEND_CHOSEN_HERE = True
    import matplotlib.pyplot as plt

    if style and _BACKEND_CHOSEN_HERE:
        plt.rcParams.update(STYLE)
    return plt


def series_styles(names: Sequence[str]) -> dict[str, dict]:
    """Colour, marker and line style per series name (stable in the given order)."""
    import matplotlib.pyplot as plt

    cmap = plt.get_cmap("tab10")
    return {n: {"color": cmap(i % 10), "marker": MARKERS[i % len(MARKERS)],
                "linestyle": LINESTYLES[i % len(LINESTYLES)]} for i, n in enumerate(names)}


def plain_log_axis(ax, axis: str = "y") -> None:
    """Log scale with plain decimal tick labels ("6", "0.3"), never "6x10^0"."""
    (ax.set_yscale if axis == "y" else ax.set_xscale)("log")
    plain_log_ticks(ax.yaxis if axis == "y" else ax.xaxis)


def plain_log_ticks(target, subs: Sequence[float] = (1.0, 2.0, 5.0)) -> None:
    """Plain decimal labels at `subs` per decade on an axis that is already logarithmic (e.g.
    a LogNorm colour bar's `cbar.ax.yaxis`; subs=(1,) for a span of many decades)."""
    from matplotlib.ticker import FuncFormatter, LogLocator

    def fmt(value: float, _pos=None) -> str:
        if value <= 0:
            return ""
        return f"{value:.6g}" if value >= 1e-3 else f"{value:.0e}"

    target.set_major_locator(LogLocator(base=10.0, subs=tuple(subs)))
    target.set_major_formatter(FuncFormatter(fmt))
    target.set_minor_formatter(FuncFormatter(lambda v, p=None: ""))


def legend_below(fig, handles: Iterable, labels: Iterable[str], ncol: int = 2, bottom: float = 0.0):
    """One figure legend under the panels (outside every axes); returns it."""
    return fig.legend(list(handles), list(labels), loc="lower center", bbox_to_anchor=(0.5, bottom),
                      ncol=ncol, frameon=False, handlelength=2.6, columnspacing=1.2)


def shade_outages(ax, outages_s: Iterable[Sequence[float]], label: bool = True) -> None:
    """Grey bands over GPS outages (s on the x axis)."""
    for i, (a, b) in enumerate(outages_s):
        ax.axvspan(a, b, color="0.85", zorder=0, lw=0, label="GPS outage" if (label and i == 0) else None)


def save(fig, path) -> None:
    """Save at the shared DPI with tight bounds (keeps the outside legend) and close."""
    import matplotlib.pyplot as plt

    fig.savefig(path, dpi=DPI, bbox_inches="tight", pad_inches=0.03)
    plt.close(fig)
