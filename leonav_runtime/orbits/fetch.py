"""Download current element sets from CelesTrak into a local cache.

`fetch_group("starlink")` GETs
`https://celestrak.org/NORAD/elements/gp.php?GROUP=starlink&FORMAT=json` (OMM JSON: no
5-digit catalogue-number limit, which TLE text runs out of) and writes
`<cache>/<name>.omm.json` and a sidecar `<cache>/<name>.omm.json.meta.json` with the
download time (UTC), URL and count. `fmt="tle"` / `"xml"` fetch TLE text (`<name>.tle`) or
OMM XML (`<name>.omm.xml`) instead. `<name>` is leonav's name of the group: `gps` (the
built-in constellation's name) is CelesTrak's `gps-ops`, which is accepted as well. The cache is `$XDG_CACHE_HOME/leonav/tle`, else
`~/.cache/leonav/tle`. CelesTrak asks users not to download the same group more than
once per update (about every 2 h); reuse the cached file.

A download never damages a good cache:
- `timeout_s` is the deadline of the whole download (connect, redirects, every read), so
  a server that drips bytes cannot hold the command past it;
- the reply may hold at most `max_bytes` (64 MB by default; CelesTrak's largest TLE group
  is a few MB): a larger Content-Length is refused before reading, a longer body is cut
  off and refused; a body shorter than its Content-Length is refused;
- the reply must parse cleanly (no rejected entry) and, when a cache of the group exists,
  hold at least `MIN_KEEP_FRACTION` (90 %) of its element sets: a truncated download
  that still parses (32 satellites -> 6) is refused and the cache kept. `force=True`
  (`leonav tle fetch --force`) accepts such a reply;
- the reply is written to a temporary file in the cache folder and renamed over the old
  file (atomic), so an interrupted or failed write leaves the old file in place.
Only http:// and https:// URLs are fetched; a malformed `url_base` is a UserInputError.
"""
from __future__ import annotations

import datetime as _dt
import errno as _errno
import http.client
import json
import logging
import math
import os
import re
import socket
import ssl
import tempfile
import threading
import time
import urllib.parse
import warnings
from pathlib import Path

from leonav_runtime import __version__
from leonav_runtime.common.errors import UserInputError
from leonav_runtime.orbits.elements import load_elements, parse_elements_text

log = logging.getLogger("leonav.orbits.fetch")

CELESTRAK_URL_BASE = "https://celestrak.org/NORAD/elements/gp.php"
KNOWN_GROUPS = ("starlink", "gps", "gnss", "oneweb", "iridium-NEXT", "stations", "active")
CELESTRAK_GROUP = {"gps": "gps-ops"}   # leonav name -> CelesTrak GROUP
ALIASES = {"gps-ops": "gps"}           # accepted spellings -> leonav name
FORMATS = {"tle": ".tle", "json": ".omm.json", "xml": ".omm.xml"}  # FORMAT= value -> cache suffix
DEFAULT_FORMAT = "json"
_GROUP_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")

DEFAULT_TIMEOUT_S = 60.0
MAX_TIMEOUT_S = 3600.0
DEFAULT_MAX_BYTES = 64_000_000
MIN_KEEP_FRACTION = 0.9
MAX_REDIRECTS = 5
_READ_BYTES = 1 << 16


class FetchError(UserInputError):
    """The download failed (offline, server unreachable, HTTP error, or not element data)."""


def default_cache_dir() -> Path:
    """`$XDG_CACHE_HOME/leonav/tle` or `~/.cache/leonav/tle`."""
    root = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(root) / "leonav" / "tle"


def canonical_group(group: str) -> str:
    """leonav's name of a group (`gps-ops` -> `gps`); other names unchanged."""
    return ALIASES.get(group, group)


def sidecar_path(path: Path) -> Path:
    """The JSON sidecar (download time, URL, count) of a cached element file."""
    return path.with_name(path.name + ".meta.json")


def group_url(group: str, url_base: str | None = None, fmt: str = DEFAULT_FORMAT) -> str:
    """The GP query URL of a group (leonav or CelesTrak name) in format `fmt` (tle/json/xml)."""
    name = canonical_group(group)
    query = urllib.parse.urlencode({"GROUP": CELESTRAK_GROUP.get(name, name), "FORMAT": fmt})
    return f"{url_base or CELESTRAK_URL_BASE}?{query}"


def _check_url(url: str, what: str) -> urllib.parse.SplitResult:
    """The parts of an http(s) URL with a host; UserInputError naming `what` otherwise."""
    shown = url if len(url) <= 200 else url[:200] + "..."
    try:
        parts = urllib.parse.urlsplit(url)
        parts.port  # noqa: B018 (raises ValueError for a port that is not a number in range)
    except ValueError as exc:
        raise UserInputError(f"{what} {shown!r}: not a valid URL ({exc}); expected http(s)://HOST/PATH") from None
    if parts.scheme not in ("http", "https"):
        raise UserInputError(f"{what} {shown!r}: expected an http:// or https:// URL")
    if not parts.hostname:
        raise UserInputError(f"{what} {shown!r}: no host name; expected http(s)://HOST/PATH")
    if any(ord(c) < 33 or ord(c) == 127 for c in url):
        raise UserInputError(f"{what} {shown!r}: contains spaces or control characters")
    return parts


def _check_limits(timeout_s: float, max_bytes: int) -> None:
    try:
        t = float(timeout_s)
    except (TypeError, ValueError):
        t = math.nan
    if not (math.isfinite(t) and 0 < t <= MAX_TIMEOUT_S):
        raise UserInputError(f"--timeout: {timeout_s!r}: expected a number of seconds in (0, {MAX_TIMEOUT_S:g}]")
    if not (isinstance(max_bytes, int) and max_bytes > 0):
        raise UserInputError(f"--max-mb: {max_bytes!r} bytes: expected a positive size")


def _shut(sock: socket.socket, fired: threading.Event) -> None:
    """Deadline reached: end every blocked read on `sock` (its owner then sees end of file)."""
    fired.set()
    try:
        socket.socket.shutdown(sock, socket.SHUT_RDWR)  # the plain socket's, also under TLS
    except OSError:
        pass


def _download(url: str, timeout_s: float, max_bytes: int) -> bytes:
    """GET `url` within `timeout_s` in total; the body (at most `max_bytes`) or FetchError.

    Each socket operation waits at most the time left, and a timer shuts the socket at
    the deadline, so neither a silent nor a dripping server (a byte now and then, in the
    headers or the body) can hold the download longer.
    """
    deadline = time.monotonic() + timeout_s
    late = FetchError(f"{url}: download did not finish within --timeout {timeout_s:g} s "
                      "(server too slow?); the cache is unchanged")

    def remaining() -> float:
        left = deadline - time.monotonic()
        if left <= 0:
            raise late
        return left

    for _ in range(MAX_REDIRECTS + 1):
        parts = _check_url(url, "URL")
        cls = http.client.HTTPSConnection if parts.scheme == "https" else http.client.HTTPConnection
        conn = cls(parts.hostname, parts.port, timeout=remaining())
        fired = threading.Event()
        watchdog = None
        try:
            conn.connect()
            sock = conn.sock  # kept: the response reads through it even after conn lets go of it
            watchdog = threading.Timer(remaining(), _shut, args=(sock, fired))
            watchdog.daemon = True
            watchdog.start()
            target = (parts.path or "/") + (f"?{parts.query}" if parts.query else "")
            conn.request("GET", target, headers={"User-Agent": f"leonav/{__version__}",
                                                 "Accept-Encoding": "identity"})
            sock.settimeout(remaining())
            reply = conn.getresponse()
            if reply.status in (301, 302, 303, 307, 308) and reply.getheader("Location"):
                url = urllib.parse.urljoin(url, reply.getheader("Location"))
                continue
            if reply.status != 200:
                raise FetchError(f"{url}: HTTP {reply.status} {reply.reason} "
                                 f"(is the group a CelesTrak group?)")
            declared = reply.getheader("Content-Length")
            length = int(declared) if declared and declared.strip().isdigit() and not reply.chunked else None
            if length is not None and length > max_bytes:
                raise FetchError(f"{url}: reply of {length / 1e6:.1f} MB is larger than the limit of "
                                 f"{max_bytes / 1e6:g} MB (raise it with --max-mb)")
            body = bytearray()
            while not reply.isclosed():  # closed once Content-Length bytes are in (it owns the socket then)
                sock.settimeout(remaining())
                piece = reply.read1(min(_READ_BYTES, max_bytes + 1 - len(body)))  # one socket read at most
                if not piece:
                    break
                body += piece
                if len(body) > max_bytes:
                    raise FetchError(f"{url}: reply is larger than the limit of {max_bytes / 1e6:g} MB "
                                     "(raise it with --max-mb)")
            if fired.is_set():
                raise late
            if length is not None and len(body) < length:
                raise FetchError(f"{url}: reply ended after {len(body)} of the {length} bytes its "
                                 "Content-Length announced (connection dropped?); the cache is unchanged")
            return bytes(body)
        except UserInputError:
            raise
        except Exception as exc:  # noqa: BLE001 (whatever the socket, TLS or HTTP layer says, one message)
            if fired.is_set() or time.monotonic() >= deadline:
                raise late from None
            if isinstance(exc, (socket.timeout, TimeoutError)):
                raise FetchError(f"{url}: no data within --timeout {timeout_s:g} s; the cache is unchanged") from None
            if isinstance(exc, http.client.HTTPException):
                raise FetchError(f"{url}: broken HTTP reply ({type(exc).__name__}: {exc}); "
                                 "the cache is unchanged") from None
            if isinstance(exc, ssl.SSLError):
                raise FetchError(f"{url}: TLS error ({exc.reason or exc}); the cache is unchanged") from None
            if isinstance(exc, (OSError, ValueError)):
                reason = getattr(exc, "strerror", None) or exc
                raise FetchError(f"{url}: cannot download ({reason}); are you offline? Use a local file "
                                 "or the built-in constellations instead") from None
            raise
        finally:
            if watchdog is not None:
                watchdog.cancel()
            conn.close()
    raise FetchError(f"{url}: more than {MAX_REDIRECTS} redirects")


def _cached_count(path: Path) -> int | None:
    """Element sets in the current cache file (None when there is none or it is unreadable)."""
    try:
        if not path.is_file():
            return None
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return len(load_elements(path))  # bounded by the element-file size limit
    except (OSError, UserInputError):
        return None


def _write_atomic(target: Path, data: bytes) -> None:
    """Write `data` to a temporary file beside `target`, then rename it over `target`."""
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".part")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def _cache_error(exc: OSError, where: Path) -> OSError:
    code = exc.errno or _errno.EIO
    reason = (exc.strerror or str(exc)).lower()
    return OSError(code, f"cannot write the TLE cache ({reason}); choose another folder with --cache", str(where))


def fetch_group(
    group: str,
    *,
    cache_dir: str | Path | None = None,
    url_base: str | None = None,
    timeout_s: float = DEFAULT_TIMEOUT_S,
    max_bytes: int = DEFAULT_MAX_BYTES,
    force: bool = False,
    fmt: str = DEFAULT_FORMAT,
) -> Path:
    """Download a CelesTrak group (e.g. 'starlink', 'gps') in `fmt` ('json' OMM by default,
    'xml' OMM, 'tle') and return the cached file's path.

    Raises FetchError (a UserInputError) when the server cannot be reached, answers with
    an HTTP error, is slower than `timeout_s` in total, sends more than `max_bytes`, or
    sends something that is not clean element data or much smaller than the cached group
    (see the module notes; `force=True` accepts the last two). A cache that cannot be
    written raises OSError naming the folder. On any error the cache is unchanged.
    """
    if not _GROUP_NAME.match(group):
        raise UserInputError(f"group {group!r}: expected a CelesTrak group name such as "
                             f"{', '.join(KNOWN_GROUPS[:3])}")
    if fmt not in FORMATS:
        raise UserInputError(f"--format {fmt!r}: expected one of {', '.join(FORMATS)}")
    _check_limits(timeout_s, max_bytes)
    if url_base is not None:
        _check_url(url_base, "--url-base")
    name = canonical_group(group)
    url = group_url(name, url_base, fmt)
    log.info("GET %s (deadline %g s, at most %d bytes)", url, timeout_s, max_bytes)
    body = _download(url, float(timeout_s), max_bytes)
    log.info("received %d bytes", len(body))
    downloaded = _dt.datetime.now(_dt.timezone.utc)

    text = body.decode("utf-8", errors="replace")
    from leonav_runtime.orbits.omm import detect_omm_format

    got = detect_omm_format(text) or "tle"
    if text.strip() and got != fmt:
        first = text.strip().splitlines()[0][:80]
        raise FetchError(f"{url}: reply is {got.upper()} data where {fmt.upper()} was asked "
                         f"(first line {first!r}); the cache is unchanged")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # rejections are judged below
            elements = parse_elements_text(text, source=url)
    except UserInputError as exc:
        first = text.strip().splitlines()[0][:80] if text.strip() else "(empty reply)"
        raise FetchError(f"{url}: reply is not element data (first line {first!r}): {exc}") from None

    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    path = cache / f"{name}{FORMATS[fmt]}"
    previous = _cached_count(path)
    problems = []
    if elements.rejected:
        first = elements.rejected[0]
        problems.append(f"{len(elements.rejected)} rejected entries (first: line {first.line}: {first.reason})")
    if previous is not None and len(elements) < MIN_KEEP_FRACTION * previous:
        problems.append(f"only {len(elements)} element sets where the cached {path.name} has {previous} "
                        f"(less than {MIN_KEEP_FRACTION:.0%}: a truncated download?)")
    if problems and not force:
        raise FetchError(f"{url}: reply refused, {'; '.join(problems)}; the cache is unchanged "
                         "(use --force to accept it)")

    epochs = sorted(elements.epochs_utc)
    sidecar = {
        "group": name,
        "format": fmt,
        "url": url,
        "downloaded_utc": downloaded.isoformat(),
        "count": len(elements),
        "rejected": len(elements.rejected),
        "epoch_min_utc": epochs[0].isoformat(),
        "epoch_max_utc": epochs[-1].isoformat(),
        "file": path.name,
        "bytes": len(body),
        "previous_count": previous,
        "forced": bool(problems),
        "problems": problems,
    }
    try:
        cache.mkdir(parents=True, exist_ok=True)
        _write_atomic(path, body)
        _write_atomic(sidecar_path(path), (json.dumps(sidecar, indent=2) + "\n").encode())
    except OSError as exc:
        where = cache if not cache.is_dir() else path
        raise _cache_error(exc, where) from None
    return path
