"""Exceptions that carry a message meant for the user (file, line, field, expectation).

`UserInputError` is defined in `hardware/errors.py` (the device layer raises it too and
must not import the runtime); this module is its runtime name, so `except UserInputError`
catches the errors of both layers.
"""
from __future__ import annotations

from leonav.hardware.errors import UserInputError

__all__ = ["UserInputError"]
