"""Mutant catalogue, runtime: dataset/, nav/, live/, observability/, beacons/ (doppler, ridges, waterfall, pipeline).

Same rules as benchmarks/mutants.py: one realistic bug per entry, each edit's text occurs once.
"""
from __future__ import annotations

from mutants import MODULES, mutant  # noqa: F401
