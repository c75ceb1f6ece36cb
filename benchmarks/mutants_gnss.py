"""Mutant catalogue, GNSS: rinex obs/nav, spp/signals, broadcast/ephemeris, gnss_ekf/coupled, lnav/sfrbx, orbits/eop.

Same rules as benchmarks/mutants.py: one realistic bug per entry, each edit's text occurs once.
"""
from __future__ import annotations

from mutants import MODULES, mutant  # noqa: F401
