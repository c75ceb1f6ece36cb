"""Observability along a run (numeric; no casadi, no models/)."""
from __future__ import annotations

from leonav_runtime.compiled import GEN_DIR, load_layout
from leonav_runtime.scenario import MODE_OBSERVABLES

GNSS_FIX_MODE = "gnss-fix+imu"


def analysis_modes() -> dict[str, tuple[str, ...]]:
    """Modes analysed: the filter's `MODE_OBSERVABLES` plus a GNSS position-fix mode (pos_*)."""
    layout = load_layout(GEN_DIR)
    modes = {k: tuple(v) for k, v in MODE_OBSERVABLES.items()}
    modes[GNSS_FIX_MODE] = tuple(s for s in layout.MEAS_SUFFIXES if s.startswith("pos_"))
    return modes
