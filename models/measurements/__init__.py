"""Measurement models h(x, aux, p), one module per observable (see models.state.MEASUREMENTS).

`MODELS` maps the observable's function suffix to its h; it is filled by `models()` so that
importing this package has no side effects beyond importing the modules.
"""
from __future__ import annotations


def models() -> dict:
    """{suffix: h(x, aux, p) -> scalar SX} for every observable, in models.state.MEASUREMENTS order."""
    from leonav.models.measurements import (doppler, doppler_rate, gnss_code, gnss_fix, gnss_pseudorange,
                                     motion_constraints, ofdm_range_difference)
    from leonav.models.state import MEASUREMENTS

    table = {
        "pseudorange": gnss_pseudorange.h,
        "pos_e": gnss_fix.h_pos_e, "pos_n": gnss_fix.h_pos_n, "pos_u": gnss_fix.h_pos_u,
        "vel_e": gnss_fix.h_vel_e, "vel_n": gnss_fix.h_vel_n, "vel_u": gnss_fix.h_vel_u,
        "doppler_rate": doppler_rate.h,
        "doppler": doppler.h,
        "ofdm_range_diff": ofdm_range_difference.h,
        "gnss_pseudorange": gnss_code.h_pseudorange,
        "gnss_range_rate": gnss_code.h_range_rate,
        "nhc_y": motion_constraints.h_nhc_y, "nhc_z": motion_constraints.h_nhc_z,
        "zupt_e": motion_constraints.h_zupt_e, "zupt_n": motion_constraints.h_zupt_n,
        "zupt_u": motion_constraints.h_zupt_u,
    }
    return {m.suffix: table[m.suffix] for m in MEASUREMENTS}
