"""Exceptions that carry a message meant for the user (file, line, field, expectation)."""
from __future__ import annotations


class UserInputError(ValueError):
    """Bad input from a user: the message names the file/line/field and what was expected.

    The CLI prints it as one line and exits with status 2, without a traceback.
    """
