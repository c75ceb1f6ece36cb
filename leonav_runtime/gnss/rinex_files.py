"""RINEX files as the field distributes them: plain, gzip (`.gz`), unix compress (`.Z`), bzip2
(`.bz2`) and Hatanaka-compressed observation files (Compact RINEX: `.crx`, `.YYd`, and those
compressed again: `.crx.gz`, `.YYd.Z`).

The format is told from the content, never from the name: the first bytes (gzip 1f 8b, compress
1f 9d, bzip2 "BZh") and then the first line ("CRINEX VERS   / TYPE" in columns 61-80). gzip and
bzip2 come from the standard library; `.Z` through the `ncompress` package and Compact RINEX
through the `hatanaka` package (its bundled crx2rnx, Y. Hatanaka's reference decoder), both
imported only when such a file is read.

A corrupt or truncated compressed file is one `UserInputError` naming the file and the
decompressor's reason. What a compressed file expands to is capped (2048 MB by default, the
environment variable LEONAV_MAX_RINEX_MB raises it): a small archive that would fill the
memory is refused in one line instead. The unix compress format has no end marker or checksum: a `.Z` file cut
short decompresses to a RINEX text cut short, which the readers reject by line like any cut file.
"""
from __future__ import annotations

import io
import os
import zlib
from pathlib import Path

from leonav_runtime.common.errors import UserInputError

GZIP_MAGIC = b"\x1f\x8b"
LZW_MAGIC = b"\x1f\x9d"      # unix compress (.Z)
BZIP2_MAGIC = b"BZh"
ZIP_MAGIC = b"PK\x03\x04"
CRINEX_LABEL = b"CRINEX VERS   / TYPE"
RINEX_LABEL = b"RINEX VERSION / TYPE"


def max_bytes() -> int:
    """The most a compressed RINEX file may expand to (bytes): LEONAV_MAX_RINEX_MB, default 2048."""
    text = os.environ.get("LEONAV_MAX_RINEX_MB", "")
    try:
        mb = float(text) if text else 2048.0
    except ValueError:
        raise UserInputError(f"LEONAV_MAX_RINEX_MB={text!r}: expected a number of megabytes") from None
    return int(mb * 1024 * 1024)


class _TooLarge(Exception):
    pass


def _too_large(path: Path, what: str, limit: int) -> UserInputError:
    return UserInputError(f"{path}: {what} expands to more than {limit / 2**20:g} MB (a decompression bomb? "
                          "raise the limit with LEONAV_MAX_RINEX_MB=<megabytes>)")


def _stream(decompressor, data: bytes, limit: int) -> bytes:
    """All members of a gzip/bzip2 stream, at most `limit` bytes (else _TooLarge)."""
    out, rest = [], data
    total = 0
    while rest:
        d = decompressor()
        chunk = d.decompress(rest, max_length=limit - total + 1)
        total += len(chunk)
        out.append(chunk)
        if total > limit:
            raise _TooLarge
        if not d.eof:   # within the limit and no end marker: the input ran out
            raise EOFError("compressed file ended before the end-of-stream marker was reached")
        rest = d.unused_data.lstrip(b"\0")   # gzip allows zero padding between members
    return b"".join(out)


def _gunzip(data: bytes, path: Path) -> bytes:
    limit = max_bytes()
    try:   # wbits 31: one gzip member with its header and CRC checked
        return _stream(lambda: zlib.decompressobj(31), data, limit)
    except _TooLarge:
        raise _too_large(path, "gzip data", limit) from None
    except (OSError, EOFError, zlib.error) as exc:
        raise UserInputError(f"{path}: gzip data corrupt or truncated ({exc})") from None


def _bunzip2(data: bytes, path: Path) -> bytes:
    import bz2   # only for such a file (a plain read needs none of the decoders)

    limit = max_bytes()
    try:
        return _stream(bz2.BZ2Decompressor, data, limit)
    except _TooLarge:
        raise _too_large(path, "bzip2 data", limit) from None
    except (OSError, EOFError, ValueError) as exc:
        raise UserInputError(f"{path}: bzip2 data corrupt or truncated ({exc})") from None


class _CappedBuffer(io.RawIOBase):
    """A write-only buffer that raises _TooLarge past `limit` bytes."""

    def __init__(self, limit: int) -> None:
        super().__init__()
        self.data, self.limit = bytearray(), limit

    def writable(self) -> bool:
        return True

    def write(self, b) -> int:
        self.data += b
        if len(self.data) > self.limit:
            raise _TooLarge
        return len(b)


def _uncompress(data: bytes, path: Path) -> bytes:
    try:
        import ncompress
    except ImportError:
        raise UserInputError(f"{path}: unix-compressed (.Z) file and the ncompress package is not installed "
                             "(pip install ncompress, or decompress it first: uncompress FILE)") from None
    limit = max_bytes()
    out = _CappedBuffer(limit)
    try:
        ncompress.decompress(data, out)
    except _TooLarge:
        raise _too_large(path, "unix compress (.Z) data", limit) from None
    except (ValueError, OSError) as exc:
        raise UserInputError(f"{path}: unix compress (.Z) data corrupt ({exc})") from None
    return bytes(out.data)


def _crx2rnx(data: bytes, path: Path) -> bytes:
    try:
        import hatanaka
    except ImportError:
        raise UserInputError(f"{path}: Hatanaka-compressed (Compact RINEX) file and the hatanaka package is not "
                             "installed (pip install hatanaka, or decompress it first: crx2rnx FILE)") from None
    import warnings

    with warnings.catch_warnings(record=True) as caught:   # crx2rnx's own warnings end up in the message
        warnings.simplefilter("always")
        try:
            out = hatanaka.crx2rnx(data)
        except hatanaka.HatanakaException as exc:
            raise UserInputError(f"{path}: Compact RINEX (Hatanaka) data corrupt or truncated: "
                                 f"{_one_line(str(exc))}") from None
        except OSError as exc:   # the bundled binary could not be started (no binary for this platform)
            raise UserInputError(f"{path}: cannot run crx2rnx of the hatanaka package ({exc}); decompress the "
                                 "file first with crx2rnx FILE") from None
    told = [w for w in caught if str(w.message).startswith("crx2rnx")]   # its own, not a library's
    if told:
        raise UserInputError(f"{path}: Compact RINEX (Hatanaka) data not decoded cleanly: "
                             f"{_one_line(str(told[0].message))}")
    if len(out) > max_bytes():   # crx2rnx writes it all; checked after (it expands ~3-10x, not 1000x)
        raise _too_large(path, "Compact RINEX (Hatanaka) data", max_bytes())
    return out


def _one_line(text: str) -> str:
    return " ".join(text.split())[:300]


def decompress_rinex(data: bytes, path: Path) -> bytes:
    """The RINEX bytes of a file's content `data` (bytes as stored; returned unchanged when plain).
    Layers: gzip / bzip2 / compress outside, Compact RINEX inside. UserInputError naming `path`
    when a layer is corrupt or a zip archive (not read: extract it first)."""
    head = data[:4]
    if head.startswith(GZIP_MAGIC):
        data = _gunzip(data, path)
    elif head.startswith(LZW_MAGIC):
        data = _uncompress(data, path)
    elif head.startswith(BZIP2_MAGIC):
        data = _bunzip2(data, path)
    elif head.startswith(ZIP_MAGIC):
        raise UserInputError(f"{path}: a zip archive, not a RINEX file (extract it first: unzip FILE)")
    if CRINEX_LABEL in data[:200].split(b"\n", 1)[0]:
        data = _crx2rnx(data, path)
    return data


def read_rinex_text(path: str | Path, kind: str) -> str:
    """Text of a RINEX `kind` ("navigation", "observation") file, plain or compressed (see the
    module docstring), non-ASCII bytes replaced; UserInputError naming the file when it is
    missing, a directory, or its compression is corrupt."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise UserInputError(f"{path}: {kind} file not found") from None
    except IsADirectoryError:
        raise UserInputError(f"{path}: is a directory, expected a RINEX {kind} file") from None
    return decompress_rinex(data, path).decode("ascii", errors="replace")


def looks_like_rinex(path: str | Path, kind: str = "observation") -> bool:
    """True when the file is RINEX or compressed (gzip, compress, bzip2, Compact RINEX), False
    for anything else (a u-blox log); UserInputError when missing or a directory. Reads the
    first line only: compressed files are taken as RINEX (their reader says if they are not)."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            first = fh.readline(200)
    except FileNotFoundError:
        raise UserInputError(f"{path}: {kind} file not found") from None
    except IsADirectoryError:
        raise UserInputError(f"{path}: is a directory, expected an {kind} file") from None
    if first[:4].startswith((GZIP_MAGIC, LZW_MAGIC, BZIP2_MAGIC, ZIP_MAGIC)):
        return True
    return RINEX_LABEL in first or CRINEX_LABEL in first
