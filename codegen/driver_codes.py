"""Return codes of the C driver and the per-record statuses of its run loop, defined once.

Emitted with the state layout (`LEONAV_<name>` in `state_layout.h`, `<name>` in
`state_layout.py`), so the hand-written driver (`leonav_runtime/csrc/leonav_driver.c`),
the Pi program and the Python runtime read the same numbers.

Two enums, documented in docs/design.md ("C driver API"):
- `RETURN_CODES`: what every driver function returns. One success convention: `OK` (0).
  Outcomes of a step that are not errors are positive (`GATED`, `FAILED`: the state was
  left unchanged); errors (bad arguments, workspace, record kind, layout) are negative.
- `RECORD_STATUSES`: what `leonav_run` writes per record into `leonav_run_out.status`
  (and the Python `RunResult.status`). A measurement record's status is the return code of
  its update (0, 1, 2); an IMU record's is `STATUS_IMU` (-1) when predicted, else 2. These
  values are never returned by a function, so -1 here is not an error code.
"""
from __future__ import annotations

from typing import NamedTuple


class Code(NamedTuple):
    name: str
    value: int
    doc: str


RETURN_CODES = (
    Code("OK", 0, "success: the step was applied / the value computed"),
    Code("GATED", 1, "update rejected: nis above the gate; x and P unchanged"),
    Code("FAILED", 2, "numerical failure (non-finite input or result, R < 0, S <= 0, dt < 0); x and P unchanged"),
    Code("ERR_WORK", -1, "workspace NULL, too small or not initialised"),
    Code("ERR_KIND", -2, "record kind is neither IMU, CV nor a LEONAV_MEAS_* id"),
    Code("ERR_LAYOUT", -3, "a generated function's shape does not match state_layout.h"),
    Code("ERR_ARG", -4, "a required pointer is NULL or n < 0"),
    Code("ERR_NUMERIC", -5, "PCRB / boxminus: a generated step failed, S not positive and finite, or R <= 0"),
)

RECORD_STATUSES = (
    Code("STATUS_IMU", -1, "IMU or constant-velocity record: predicted"),
    Code("STATUS_APPLIED", 0, "measurement record: applied"),
    Code("STATUS_GATED", 1, "measurement record: rejected by the gate (x, P unchanged)"),
    Code("STATUS_FAILED", 2, "IMU, constant-velocity or measurement record: numerical failure (x, P unchanged)"),
)

_ret = {c.name: c.value for c in RETURN_CODES}
_rec = {c.name: c.value for c in RECORD_STATUSES}
assert _ret["OK"] == 0 and all(c.value > 0 for c in RETURN_CODES if c.name in ("GATED", "FAILED"))
assert all(c.value < 0 for c in RETURN_CODES if c.name.startswith("ERR_"))
assert len(set(_ret.values())) == len(RETURN_CODES) and len(set(_rec.values())) == len(RECORD_STATUSES)
# a measurement record stores its update's return code
assert (_rec["STATUS_APPLIED"], _rec["STATUS_GATED"], _rec["STATUS_FAILED"]) == (_ret["OK"], _ret["GATED"], _ret["FAILED"])
