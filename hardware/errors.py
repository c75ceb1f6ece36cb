"""The one exception for bad input from a user (a file, a port, a field, a value).

Defined here, in the lowest layer that reports such errors, so device code raises it
without reaching up into the runtime; `leonav_runtime.common.errors.UserInputError` is this
same class, which the `leonav` CLI prints as one line (exit status 2, no traceback).
"""
from __future__ import annotations

__all__ = ["UserInputError"]


class UserInputError(ValueError):
    """Bad input from a user: the message names the file/line/field and what was expected.

    The CLI prints it as one line and exits with status 2, without a traceback.
    """
