"""RXM-RAWX of a recorded session -> the single-point pass of the tightly coupled modes.

The RAWX epochs are those the session's decode of gnss.raw gives (`hardware.session`):
their times are the receiver's own GPS time tags, so they need no host stamp. Broadcast
ephemerides come from the RXM-SFRBX GPS LNAV subframes in the same bytes and from RINEX
navigation files given with `--nav` (both when both are there; Klobuchar coefficients from
subframe 4 page 18, else the first RINEX header that has them). The single-point pass and
the observation table are `leonav_runtime.gnss.coupled`'s; here only what the session has
and why a mode cannot run.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from leonav_runtime.core import navfuncs
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gnss.spp import SppResult


@dataclasses.dataclass
class RawGnss:
    """spp: the single-point result of the session's RAWX (None when it cannot be made);
    summary: counts for metrics.json; reason: why the pseudorange modes cannot run ('' if they can)."""

    spp: SppResult | None
    summary: dict
    reason: str = ""


def raw_gnss(gnss_records, options, nav: navfuncs.NavFunctions, source: str) -> RawGnss:
    """The single-point pass over the RXM-RAWX / RXM-SFRBX records of a decoded session."""
    from leonav.hardware.records import RxmRawx, UbxFrame
    from leonav_runtime.gnss import coupled
    from leonav_runtime.gnss import sfrbx as _sfrbx
    from leonav_runtime.gnss.signals import klobuchar_coefficients, load_nav_files
    from leonav_runtime.gnss.ubx_log import ubx_records_to_log

    epochs = [r for r in gnss_records if isinstance(r, RxmRawx)]
    frames = [r for r in gnss_records if isinstance(r, UbxFrame)
              and (r.msg_class, r.msg_id) == (_sfrbx.SFRBX_CLASS, _sfrbx.SFRBX_ID)]
    log = ubx_records_to_log(epochs, [(f.payload, f"{source}: SFRBX #{k + 1}") for k, f in enumerate(frames)],
                             source)
    eph, klob = log.ephemerides, klobuchar_coefficients(log.iono)
    klob_source = "none" if klob is None else "SFRBX page 18"
    if options.nav_paths:
        eph2, klob2 = load_nav_files(options.nav_paths)
        eph = eph.concat(eph2).deduplicate()
        if klob is None and klob2 is not None:
            klob, klob_source = klob2, "RINEX header"
    summary = {"rawx_epochs": len(epochs), "rawx_rows": len(log.observations), "sfrbx_frames": len(frames),
               "ephemerides": len(eph), "ephemerides_from_sfrbx": len(log.ephemerides),
               "klobuchar": klob_source,
               "sfrbx_counts": {k: int(v) for k, v in sorted(log.counts.items())}}
    if not epochs:
        return RawGnss(None, summary, "no RXM-RAWX in gnss.raw (enable raw measurements on the receiver)")
    if len(eph) == 0:
        return RawGnss(None, summary, "no broadcast ephemeris: no GPS LNAV subframe in the RXM-SFRBX of gnss.raw; "
                                      "give --nav RINEX_NAV")
    try:
        spp = coupled.single_point(log.observations, eph, klob, elevation_mask_deg=options.elevation_mask_deg,
                                   nav=nav)
    except UserInputError as exc:
        return RawGnss(None, summary, str(exc))
    from leonav_runtime.gnss.gnss_ekf import MS_M, clock_jumps_m

    jumps = clock_jumps_m(spp)
    summary |= {"receiver_clock_jumps_ms": int(round(np.abs(np.diff(jumps, prepend=0.0)).sum() / MS_M)),
                "epochs_solved": int(spp.solved.sum()), "rows_by_reason": {
        k: int(v) for k, v in sorted(spp.counts.items()) if not k.startswith("epochs_")}}
    return RawGnss(spp, summary)
