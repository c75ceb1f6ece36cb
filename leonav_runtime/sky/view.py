"""Sky view from one site: which satellites are above their elevation mask, and when.

`sky_view()` propagates every element set over a time grid, keeps only the satellites
above their constellation's mask (as sparse (satellite, epoch) points, so ten thousand
satellites over a long window stay small), and counts them per epoch. The simulator reuses
the counts and the visible sets; `leonav sky` (commands/sky.py) turns a `SkyView` into
`sky.json`, `visible_counts.csv` and `sky.png` with the helpers here.

Frames and units: satellite and site positions are ECEF (m) at the same instant; azimuth
from North towards East, elevation from the WGS84 horizon (rad); time in seconds since
the window start `epoch_utc` (UTC).
"""
from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from leonav_runtime.orbits import geometry
from leonav_runtime.orbits.geometry import Site

# Elements older (or newer) than this, relative to the window, are flagged stale when the
# element set does not carry its own threshold (orbits.ElementSet.stale_after_days): SGP4
# errors for LEO grow by roughly a kilometre per day and Starlink satellites manoeuvre.
STALE_AGE_DAYS = 3.0

# Satellite-epoch positions propagated per chunk (x3 doubles, plus velocities): keeps the
# peak memory near 100 MB whatever the number of satellites and epochs.
_CHUNK_SAT_EPOCHS = 2_000_000


# The paper's hardware and simulation site on the RIT campus, Rochester NY.
ROCHESTER = Site.from_degrees(43.0848638, -77.6786127, 170.0)


@dataclass
class ConstellationView:
    """What one constellation looks like from the site over the window.

    Visible points are stored sparsely: point k is satellite `sat_index[k]` (an index into
    `names`/`norad_ids`, i.e. into the element set) at epoch `t_index[k]` with azimuth
    `az_rad[k]`, elevation `el_rad[k]` and range `range_m[k]`.
    """

    name: str
    mask_rad: float
    names: list[str]
    norad_ids: np.ndarray
    count: np.ndarray  # (nt,) visible satellites per epoch
    sat_index: np.ndarray
    t_index: np.ndarray
    az_rad: np.ndarray
    el_rad: np.ndarray
    range_m: np.ndarray
    n_loaded: int
    failures: list[tuple[str, int, str]] = field(default_factory=list)
    rejected: list[Any] = field(default_factory=list)
    ages_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    stale_after_days: float = STALE_AGE_DAYS

    @property
    def n_failed(self) -> int:
        return len(self.failures)

    def visible_at(self, k: int) -> np.ndarray:
        """Element-set indices of the satellites visible at epoch index `k`."""
        return np.sort(self.sat_index[self.t_index == k])

    def visible_whole_window(self) -> np.ndarray:
        """Element-set indices of the satellites above the mask at every epoch."""
        nt = self.count.size
        sats, n_epochs = np.unique(self.sat_index, return_counts=True)
        return sats[n_epochs == nt]

    def dense(self, nt: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(sats, az (nsat_vis, nt), el (nsat_vis, nt), visible (nsat_vis, nt)), NaN where hidden.

        Only the satellites visible at least once appear; `sats` are their indices.
        """
        sats, row = np.unique(self.sat_index, return_inverse=True)
        az = np.full((sats.size, nt), np.nan)
        el = np.full((sats.size, nt), np.nan)
        az[row, self.t_index] = self.az_rad
        el[row, self.t_index] = self.el_rad
        return sats, az, el, np.isfinite(el)


@dataclass
class SkyView:
    """Result of `sky_view`: the site, the time grid and one view per constellation."""

    site: Site
    epoch_utc: _dt.datetime
    t_s: np.ndarray
    constellations: dict[str, ConstellationView]

    def counts(self) -> dict[str, np.ndarray]:
        """Visible satellites per epoch, per constellation."""
        return {name: view.count for name, view in self.constellations.items()}

    def dop(self, name: str = "gps") -> dict | None:
        """Per-epoch DOP (geometry.dop) of the visible satellites of one constellation."""
        view = self.constellations.get(name)
        if view is None:
            return None
        _, az, el, vis = view.dense(self.t_s.size)
        # geometry.dop wants (epoch, satellite).
        return geometry.dop(az.T, el.T, vis.T)


def _propagate_default(elements: Any, epoch_utc: _dt.datetime, t_s: np.ndarray):
    # Imported lazily so this module (and its tests with fake propagators) does not need
    # the orbit code at import time. Positions only (no acceleration: not needed for a sky
    # view), and no per-chunk stale warning: the summary reports element ages once.
    from leonav_runtime.orbits import propagate_ecef

    return propagate_ecef(elements, epoch_utc, t_s, acceleration=False, warn_stale=False)


def _chunks(n_sats: int, nt: int) -> list[np.ndarray]:
    per_chunk = max(1, _CHUNK_SAT_EPOCHS // max(nt, 1))
    return [np.arange(i, min(i + per_chunk, n_sats)) for i in range(0, n_sats, per_chunk)]


def _view_one(
    name: str,
    elements: Any,
    site: Site,
    epoch_utc: _dt.datetime,
    t_s: np.ndarray,
    mask_rad: float,
    propagate: Callable,
    progress: Any,
) -> ConstellationView:
    n = len(elements)
    r_rx = site.r_ecef_m
    parts: list[tuple[np.ndarray, ...]] = []
    failures: list[tuple[str, int, str]] = []
    for idx in _chunks(n, t_s.size):
        subset = elements if idx.size == n else elements.select(idx)
        states = propagate(subset, epoch_utc, t_s)
        failures.extend(states.failures)
        ok = np.broadcast_to(np.asarray(states.ok, dtype=bool).reshape(idx.size, -1), (idx.size, t_s.size))
        # SGP4 can return NaN/inf with error code 0 (elements out of its domain): never a silent
        # "not visible", always a counted failure
        finite = np.isfinite(np.asarray(states.r_ecef_m, dtype=float)).all(axis=-1).reshape(idx.size, -1)
        silent = np.nonzero(ok.all(axis=1) & ~finite.all(axis=1))[0]
        for i in silent:
            first = int(np.argmax(~finite[i]))
            failures.append((subset.names[i], int(subset.norad_ids[i]),
                             f"SGP4 returned a non-finite position without an error code; first at "
                             f"t = {t_s[first]:g} s (elements outside SGP4's domain?)"))
        ok = ok & finite
        az, el, rng = geometry.az_el_range(states.r_ecef_m, r_rx, site.lat_rad, site.lon_rad)
        vis = geometry.visible_mask(el, mask_rad) & ok
        s_local, k = np.nonzero(vis)
        parts.append((idx[s_local], k, az[s_local, k], el[s_local, k], rng[s_local, k]))
        if progress is not None:
            progress.update(idx.size)
    cat = [np.concatenate([p[i] for p in parts]) if parts else np.zeros(0) for i in range(5)]
    sat_index, t_index = cat[0].astype(np.int64), cat[1].astype(np.int64)
    count = np.bincount(t_index, minlength=t_s.size)
    return ConstellationView(
        name=name,
        mask_rad=float(mask_rad),
        names=list(elements.names),
        norad_ids=np.asarray(elements.norad_ids),
        count=count,
        sat_index=sat_index,
        t_index=t_index,
        az_rad=cat[2],
        el_rad=cat[3],
        range_m=cat[4],
        n_loaded=n,
        failures=failures,
        rejected=list(getattr(elements, "rejected", []) or []),
        ages_s=np.asarray(elements.ages_s(epoch_utc), dtype=float) if n else np.zeros(0),
        stale_after_days=float(getattr(elements, "stale_after_days", STALE_AGE_DAYS)),
    )


def sky_view(
    elements_by_constellation: Mapping[str, Any],
    site: Site,
    epoch_utc: _dt.datetime,
    t_s: Sequence[float] | np.ndarray,
    masks: Mapping[str, float] | None = None,
    *,
    propagate: Callable | None = None,
    show_progress: bool = False,
) -> SkyView:
    """Satellites above their elevation mask seen from `site` over `epoch_utc + t_s`.

    elements_by_constellation: name -> ElementSet (leonav_runtime.orbits).
    site: receiver (WGS84). epoch_utc: window start (timezone-aware UTC datetime).
    t_s: epochs, seconds since `epoch_utc`. masks: name -> elevation mask (rad); missing
    names get `geometry.ELEVATION_MASK_DEFAULTS_RAD` (GPS 10 deg, Starlink 28 deg).
    propagate: `propagate_ecef(elements, epoch_utc, t_s)` replacement (tests use fakes).

    Propagation runs in satellite chunks so memory stays bounded; SGP4 failures are kept
    per satellite in `ConstellationView.failures` (never dropped silently).
    """
    t_s = np.atleast_1d(np.asarray(t_s, dtype=float))
    propagate = propagate or _propagate_default
    all_masks = geometry.masks_for(elements_by_constellation, masks)
    total = sum(len(es) for es in elements_by_constellation.values())
    progress = None
    if show_progress:
        from leonav_runtime.common.progress import progress as make_progress

        progress = make_progress(total, "propagating", "sat", leave=False)
    try:
        views = {
            name: _view_one(name, es, site, epoch_utc, t_s, all_masks[name], propagate, progress)
            for name, es in elements_by_constellation.items()
        }
    finally:
        if progress is not None:
            progress.close()
    return SkyView(site=site, epoch_utc=epoch_utc, t_s=t_s, constellations=views)


# --------------------------------------------------------------------------------------
# Summaries (sky.json) and the figure (sky.png)


def _stats(x: np.ndarray) -> dict:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {"min": None, "median": None, "max": None}
    return {"min": float(x.min()), "median": float(np.median(x)), "max": float(x.max())}


def _rejected_entry(entry: Any) -> dict:
    """One rejected element-set entry as {file, line, reason} whatever its container."""
    if all(hasattr(entry, a) for a in ("source", "line", "reason")):  # orbits.RejectedEntry
        return {"file": str(entry.source), "line": int(entry.line), "name": getattr(entry, "name", ""),
                "reason": str(entry.reason)}
    if isinstance(entry, Mapping):
        return {k: entry.get(k) for k in ("file", "line", "name", "reason")}
    if isinstance(entry, (tuple, list)) and len(entry) == 3:
        return {"file": str(entry[0]), "line": entry[1], "name": "", "reason": str(entry[2])}
    return {"file": None, "line": None, "name": "", "reason": str(entry)}


def summarize(view: SkyView) -> dict:
    """JSON-ready summary: visible counts, GPS DOP, element ages, what was left out."""
    t_s = view.t_s
    out: dict[str, Any] = {
        "site": view.site.as_dict(),
        "window": {
            "start_utc": view.epoch_utc.isoformat(),
            "end_utc": (view.epoch_utc + _dt.timedelta(seconds=float(t_s[-1]))).isoformat(),
            "duration_s": float(t_s[-1] - t_s[0]),
            "step_s": float(t_s[1] - t_s[0]) if t_s.size > 1 else 0.0,
            "n_epochs": int(t_s.size),
        },
        "masks_deg": {n: math.degrees(c.mask_rad) for n, c in view.constellations.items()},
        "visible": {},
        "element_age_days": {},
        "satellites": {},
        "left_out": {},
        "warnings": [],
    }
    for name, c in view.constellations.items():
        k_min = int(np.argmin(c.count)) if c.count.size else 0
        out["visible"][name] = {
            "min": int(c.count.min()) if c.count.size else 0,
            "max": int(c.count.max()) if c.count.size else 0,
            "mean": float(c.count.mean()) if c.count.size else 0.0,
            "current": int(c.count[0]) if c.count.size else 0,
            "t_min_s": float(t_s[k_min]),
            "whole_window": int(c.visible_whole_window().size),
            "ever": int(np.unique(c.sat_index).size),
        }
        ages_days = c.ages_s / 86400.0
        # Age at both ends of the window counts: a set is stale if either end is too far.
        span_days = float(t_s[-1] - t_s[0]) / 86400.0
        worst_days = np.maximum(np.abs(ages_days), np.abs(ages_days + span_days))
        stale = int(np.sum(worst_days > c.stale_after_days))
        out["element_age_days"][name] = {
            **_stats(ages_days),
            "n_stale": stale,
            "stale_threshold_days": c.stale_after_days,
        }
        if stale:
            out["warnings"].append(
                f"{name}: {stale} of {ages_days.size} element sets are more than {c.stale_after_days:g} days from "
                f"the window (median age {np.median(ages_days):.2f} d); their positions may be km off"
            )
        out["satellites"][name] = {
            "loaded": c.n_loaded,
            "sgp4_failed": c.n_failed,
            "rejected_entries": len(c.rejected),
        }
        out["left_out"][name] = {
            "sgp4_failures": [{"name": n, "norad": int(i), "reason": r} for n, i, r in c.failures],
            "rejected": [_rejected_entry(e) for e in c.rejected],
        }
        if c.n_failed:
            first = c.failures[0]
            out["warnings"].append(
                f"{name}: {c.n_failed} satellites left out by SGP4, first {first[0]} ({first[1]}): {first[2]} "
                "(all in left_out)"
            )
        if c.rejected:
            out["warnings"].append(
                f"{name}: {len(c.rejected)} entries rejected while loading, first {c.rejected[0]} (all in left_out)"
            )
    if "gps" in view.constellations:
        d = view.dop("gps")
        out["dop_gps"] = {key: _stats(d[key]) for key in geometry.DOP_KEYS}
        out["dop_gps"]["epochs_without_dop"] = int(np.sum(~np.isfinite(d["gdop"])))
        out["dop_gps"]["reason"] = d["reason"]
    return out


# Tracks are drawn for the first part of the window only: past ~15 minutes the Starlink
# tracks fill the whole sky above the mask and hide each other.
PLOT_TRACK_SPAN_S = 900.0
