"""UART timing: how long bytes take on a serial line (8N1: 10 bits per byte).

`serialization_s` is the one place this is computed. The recorder's clock docs
(`clock.uart_delay_profile`), `leonav replay` (a record is stamped when its *last* byte
arrives, so its stamp is late by its own serialization) and the synthetic session writer
(`fakes.serial_chunks`, byte arrival times) all use it.
"""
from __future__ import annotations

import numpy as np

__all__ = ["BITS_PER_BYTE", "serialization_s"]

BITS_PER_BYTE = 10
"""UART 8N1: start bit, 8 data bits, stop bit."""


def serialization_s(n_bytes, baud: float):
    """Time (s) to send `n_bytes` (a count or an array of counts) back to back at `baud` (bit/s)."""
    if isinstance(n_bytes, (list, tuple)):
        n_bytes = np.asarray(n_bytes, float)
    return n_bytes * BITS_PER_BYTE / baud
