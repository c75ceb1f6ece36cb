"""Tracked carrier-phase epochs -> the time differences of the `CARRIER_PHASE` observable.

The carrier tracker (`beacons.carrier`, `carrier_hook.track_result`) gives per tone and per
epoch the accumulated phase Phi (cycles, one integer ambiguity per arc), its 1-sigma, a lock
flag and an arc number. The filter's observable is z = Phi(t) - Phi(t - T) over one tracker
epoch T (models/measurements/carrier_phase.py). `phase_differences` makes them: consecutive
epochs of the same tone and the same arc, both locked, finite, spaced by the tracker's epoch
within `tol_s`; z = Phi_k - Phi_{k-1}, sigma = sqrt(s_k^2 + s_{k-1}^2), interval = t_k - t_{k-1}.
Every pair of consecutive epochs of a tone that does not make a difference is counted under
one reason (first that applies): `unlocked` (either end not locked), `non_finite` (a phase or
sigma not finite, or sigma <= 0, while locked), `new_arc` (the arc changes: a detected slip or
a relock), `gap` (spacing not T within tol_s). Nothing is dropped without being counted:
pairs = differences + the sum of the breaks, pairs = epochs - tones.

A tone off the channel centre (`tone_to_centre`): the tracked baseband phase of tone k rises
with its frequency, df = k * comb spacing from the centre, so over an interval T

    dPhi_k = T (df + b_lo) - ((f_c + df)/c) drho,

and the model is the centre's, T b_lo - (f_c/c) drho. The centre's difference is
dPhi_k - T df + (df/c) drho, with drho the predicted range change (satellite states of the
table, receiver at the origin: its own motion, ~3 m per epoch at 30 m/s, and the element set's
range-rate error leave (df/c) x a few m, < 3e-3 cycles at the outermost tone, k = 4). Not
rescaling z by f_c/(f_c + df): that would scale T b_lo too, and b_lo (the LNB's offset, up to
a few MHz) x T x df/f_c is several cycles. What stays: the SDR sample clock scales the
tone's offset as it measures it, (1 - s_clk) T df, and the model's h has no per-tone term for
it: |s_clk| T |df| = 1.8e-2 cycles at 1 ppm (a TCXO) for k = 4, 1.8 cycles at 100 ppm
(a crystal without TCXO: then only the centre tone is right).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gen.constants import C_LIGHT_MPS

BREAK_REASONS = ("unlocked", "non_finite", "new_arc", "gap")
"""Why two consecutive epochs of a tone make no difference, in the order they are tested."""
EPOCH_TOLERANCE = 0.05
"""Default spacing tolerance, as a fraction of the tracker's epoch (5 ms of 0.1 s)."""


@dataclasses.dataclass
class PhaseDifferences:
    """Time differences of tracked carrier phase: t (n,) s, the end of each interval;
    interval_s (n,) s, its length; norad_id (n,), tone_id (n,) the tone (ridge number);
    z_cycles (n,) Phi(t) - Phi(t - interval); sigma_cycles (n,) its 1-sigma; counts: tones,
    epochs, pairs, differences and `breaks` by reason (BREAK_REASONS)."""

    t: np.ndarray
    interval_s: np.ndarray
    norad_id: np.ndarray
    tone_id: np.ndarray
    z_cycles: np.ndarray
    sigma_cycles: np.ndarray
    counts: dict

    @property
    def t_prev(self) -> np.ndarray:
        """Start of each interval (s)."""
        return self.t - self.interval_s


def _column(name: str, values, n: int, dtype=float) -> np.ndarray:
    arr = np.asarray(values, dtype)
    if arr.shape != (n,):
        raise UserInputError(f"carrier-phase epochs: {name}: shape {arr.shape}, expected ({n},) like t_s")
    return arr


def phase_differences(t_s, norad_id, tone_id, phase_cycles, sigma_phase_cycles, locked, arc,
                      epoch_s: float, tol_s: float | None = None) -> PhaseDifferences:
    """Time differences of per-tone tracked phase epochs (module doc).

    t_s (n,) s; norad_id (n,) and tone_id (n,) int: the tone's satellite and its own id (the
    ridge number: unique per tone in a capture); phase_cycles, sigma_phase_cycles (n,)
    cycles; locked (n,) bool; arc (n,) int; epoch_s the tracker's epoch (s, > 0); tol_s the
    spacing tolerance (s; default EPOCH_TOLERANCE x epoch_s). Epochs may come in any order."""
    t = np.asarray(t_s, float)
    if t.ndim != 1:
        raise UserInputError(f"carrier-phase epochs: t_s: shape {t.shape}, expected (n,)")
    n = t.size
    sat = _column("norad_id", norad_id, n, np.int64)
    tone = _column("tone_id", tone_id, n, np.int64)
    phi = _column("phase_cycles", phase_cycles, n)
    sig = _column("sigma_phase_cycles", sigma_phase_cycles, n)
    lk = _column("locked", locked, n, bool)
    arcs = _column("arc", arc, n, np.int64)
    if not (np.isfinite(epoch_s) and epoch_s > 0):
        raise UserInputError(f"carrier-phase epochs: epoch_s {epoch_s!r}: expected a positive number of seconds")
    tol = EPOCH_TOLERANCE * epoch_s if tol_s is None else float(tol_s)
    order = np.lexsort((t, tone, sat))
    t, sat, tone, phi, sig, lk, arcs = (a[order] for a in (t, sat, tone, phi, sig, lk, arcs))
    same = (sat[1:] == sat[:-1]) & (tone[1:] == tone[:-1])     # pair (k-1, k) inside one tone
    ok_end = np.isfinite(phi) & np.isfinite(sig) & (sig > 0) & np.isfinite(t)
    dt = np.diff(t)
    unlocked = same & ~(lk[1:] & lk[:-1])
    non_finite = same & ~unlocked & ~(ok_end[1:] & ok_end[:-1])
    new_arc = same & ~unlocked & ~non_finite & (arcs[1:] != arcs[:-1])
    with np.errstate(invalid="ignore"):
        gap = same & ~unlocked & ~non_finite & ~new_arc & ~(np.abs(dt - epoch_s) <= tol)
    good = same & ~(unlocked | non_finite | new_arc | gap)
    k = np.nonzero(good)[0] + 1
    n_tones = int(np.unique(np.stack([sat, tone]), axis=1).shape[1]) if n else 0
    counts = {"tones": n_tones, "epochs": n, "pairs": int(same.sum()), "differences": int(k.size),
              "breaks": {"unlocked": int(unlocked.sum()), "non_finite": int(non_finite.sum()),
                         "new_arc": int(new_arc.sum()), "gap": int(gap.sum())}}
    return PhaseDifferences(t[k], t[k] - t[k - 1], sat[k], tone[k], phi[k] - phi[k - 1],
                            np.hypot(sig[k], sig[k - 1]), counts)


def tone_to_centre(z_cycles, interval_s, tone_offset_hz, drho_pred_m) -> np.ndarray:
    """A tone's phase differences (cycles) referred to the channel centre f_c (module doc):
    z - interval df + (df/c) drho, with tone_offset_hz df (Hz, the tone minus the centre),
    interval_s (s) and drho_pred_m the predicted range change over the interval (m)."""
    df = np.asarray(tone_offset_hz, float)
    return (np.asarray(z_cycles, float) - np.asarray(interval_s, float) * df
            + df / C_LIGHT_MPS * np.asarray(drho_pred_m, float))
