"""Measurement models, one module per sensor: its observables' h(x, aux, p) and, at the module's
top, its registry entries (`STATES`, `PARAMS`, `OBSERVABLES`; see `leonav.models.registry`).

Adding a sensor is one file here (`leonav codegen new-observable NAME` writes a template) and
`leonav codegen`: the layout, the generated functions and every list of the runtime follow.
"""
from __future__ import annotations


def models() -> dict:
    """{suffix: h(x, aux, p) -> scalar SX} for every observable, in kind-id order."""
    from leonav.models.state import MEASUREMENTS

    return {m.suffix: m.h for m in MEASUREMENTS}
