"""UTC times given by users (CLI options, metadata fields, scenario files)."""
from __future__ import annotations

import datetime as _dt

from leonav_runtime.common.errors import UserInputError


def parse_utc(text: str, where: str, *, require_zone: bool = False) -> _dt.datetime:
    """ISO 8601 time -> timezone-aware UTC datetime.

    'Z' or an offset is accepted; a time without a zone is taken as UTC, or rejected with
    `require_zone` (scenario files, where an unstated zone is more likely a mistake).
    `where` names the option or field in the error. Anything else than text, a time that is
    not ISO 8601 and one whose UTC falls outside years 1..9999 (e.g. 0001-01-01T00:00+01:00)
    are a UserInputError naming `where`.
    """
    if not isinstance(text, str):
        raise UserInputError(f"{where}: expected an ISO 8601 time as text, got {type(text).__name__} "
                             "(e.g. \"2026-02-23T12:00:00Z\")")
    s = text.strip()
    if s.endswith(("Z", "z")):
        s = s[:-1] + "+00:00"
    try:
        t = _dt.datetime.fromisoformat(s)
    except ValueError:
        raise UserInputError(
            f"{where}: {text!r} is not an ISO 8601 time; expected e.g. 2026-02-23T12:00:00Z"
        ) from None
    if t.tzinfo is None:
        if require_zone:
            raise UserInputError(f"{where}: {text!r} has no time zone: expected an explicit one, e.g. "
                                 f"{s}Z for UTC or {s}+01:00 (a time without one is not guessed)")
        t = t.replace(tzinfo=_dt.timezone.utc)
    try:
        return t.astimezone(_dt.timezone.utc)
    except OverflowError:
        raise UserInputError(f"{where}: {text!r} is out of range: its UTC is before year 1 or after 9999") from None
