"""Download current element sets from CelesTrak into a local cache.

`fetch_group("starlink")` GETs
`https://celestrak.org/NORAD/elements/gp.php?GROUP=starlink&FORMAT=tle`, parses the reply
(so an HTML error page or a truncated download is caught before it replaces a good
file), writes `<cache>/<group>.tle` and a JSON sidecar `<cache>/<group>.json` with the
download time (UTC), URL and count. The cache is `$XDG_CACHE_HOME/leonav/tle`, else
`~/.cache/leonav/tle`. CelesTrak asks users not to download the same group more than
once per update (about every 2 h); reuse the cached file.
"""
from __future__ import annotations

import datetime as _dt
import json
import os
import re
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path

from leonav_runtime import __version__
from leonav_runtime.errors import UserInputError
from leonav_runtime.orbits.elements import parse_elements_text

CELESTRAK_URL_BASE = "https://celestrak.org/NORAD/elements/gp.php"
KNOWN_GROUPS = ("starlink", "gps-ops", "gnss", "oneweb", "iridium-NEXT", "stations", "active")
_GROUP_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


class FetchError(UserInputError):
    """The download failed (offline, server unreachable, HTTP error, or not element data)."""


def default_cache_dir() -> Path:
    """`$XDG_CACHE_HOME/leonav/tle` or `~/.cache/leonav/tle`."""
    root = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(root) / "leonav" / "tle"


def group_url(group: str, url_base: str | None = None) -> str:
    """The GP query URL of a CelesTrak group in TLE format."""
    query = urllib.parse.urlencode({"GROUP": group, "FORMAT": "tle"})
    return f"{url_base or CELESTRAK_URL_BASE}?{query}"


def fetch_group(
    group: str,
    *,
    cache_dir: str | Path | None = None,
    url_base: str | None = None,
    timeout_s: float = 20.0,
) -> Path:
    """Download a CelesTrak group (e.g. 'starlink', 'gps-ops') and return the cached TLE path.

    Raises FetchError (a UserInputError) when the server cannot be reached, answers with
    an HTTP error, or sends something that contains no valid element set.
    """
    if not _GROUP_NAME.match(group):
        raise UserInputError(f"group {group!r}: expected a CelesTrak group name such as "
                             f"{', '.join(KNOWN_GROUPS[:3])}")
    url = group_url(group, url_base)
    request = urllib.request.Request(url, headers={"User-Agent": f"leonav/{__version__}"})
    try:
        with urllib.request.urlopen(request, timeout=timeout_s) as reply:
            body = reply.read()
    except urllib.error.HTTPError as exc:
        raise FetchError(f"{url}: HTTP {exc.code} {exc.reason} (is {group!r} a CelesTrak group?)") from None
    except (urllib.error.URLError, OSError) as exc:
        reason = getattr(exc, "reason", exc)
        raise FetchError(f"{url}: cannot download ({reason}); are you offline? Use a local file "
                         "or the built-in constellations instead") from None
    text = body.decode("utf-8", errors="replace")
    downloaded = _dt.datetime.now(_dt.timezone.utc)
    try:
        elements = parse_elements_text(text, source=url)
    except UserInputError as exc:
        first = text.strip().splitlines()[0][:80] if text.strip() else "(empty reply)"
        raise FetchError(f"{url}: reply is not element data (first line {first!r}): {exc}") from None

    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    cache.mkdir(parents=True, exist_ok=True)
    path = cache / f"{group}.tle"
    tmp = path.with_suffix(".tle.part")
    tmp.write_text(text)
    os.replace(tmp, path)  # a failed download never leaves a half-written file behind
    epochs = sorted(elements.epochs_utc)
    sidecar = {
        "group": group,
        "url": url,
        "downloaded_utc": downloaded.isoformat(),
        "count": len(elements),
        "rejected": len(elements.rejected),
        "epoch_min_utc": epochs[0].isoformat(),
        "epoch_max_utc": epochs[-1].isoformat(),
        "file": path.name,
    }
    path.with_suffix(".json").write_text(json.dumps(sidecar, indent=2) + "\n")
    return path
