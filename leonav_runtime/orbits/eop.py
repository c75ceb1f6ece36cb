"""Earth orientation parameters: UT1-UTC and polar motion from the IERS tables.

TEME -> ECEF needs GMST on UT1 and, to the centimetre, the pole's position. UT1-UTC is
up to 0.9 s (about 400 m of Earth rotation at the equator); ignoring its 0.07 s of
February 2026 moves a receiver 21 m east as seen from the satellites and biases the
Starlink Doppler rate by up to 0.25 Hz/s. Polar motion is a few metres.

Source: the IERS Rapid Service / Prediction Centre table `finals2000A.all` (Bulletin A:
daily measured values and one year of predictions), as shipped by the `astropy-iers-data`
package (updated on PyPI every few weeks: `pip install -U astropy-iers-data`). Another
file in the same format can be given with `LEONAV_EOP_FILE` or `EopTable.load(path)`.

Between the daily rows the values are interpolated linearly in time; a leap second
(a 1 s jump of UT1-UTC between two days) is unwrapped before interpolation and put back
after, so the day of a leap second is exact. Units: UT1-UTC in s, polar motion in rad.

Parsing the 20,000 rows costs about 50 ms of CPU, paid by every command that propagates; the
parsed table is kept in the user's cache as a NumPy `.npz` (`$LEONAV_EOP_CACHE`, `off` turns it
off, else `$XDG_CACHE_HOME/leonav/eop`, else `~/.cache/leonav/eop`), keyed by the SHA-256 of the
file's bytes and of this module's source, so an edited table (whatever its time stamp) or parser
is a miss. An entry that cannot be read or does not check out (key, shapes, types, increasing
MJD) is ignored and rewritten (temporary name, then renamed); at most `CACHE_MAX_ENTRIES` are
kept, the least recently used removed first; files under `CACHE_MIN_BYTES` are parsed directly.
"""
from __future__ import annotations

import datetime as _dt
import functools
import hashlib
import logging
import math
import os
import warnings
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from leonav_runtime.common.errors import UserInputError

ARCSEC_RAD = math.pi / (180.0 * 3600.0)
MJD_UNIX_EPOCH = 40587.0          # MJD of 1970-01-01T00:00:00 UTC
PREDICTION_STALE_DAYS = 30.0      # warn when the values used are predictions this far ahead of the last measurement
ENV_FILE = "LEONAV_EOP_FILE"
CACHE_ENV = "LEONAV_EOP_CACHE"
CACHE_FORMAT = 1
CACHE_MAX_ENTRIES = 4
CACHE_MIN_BYTES = 64 * 1024
_log = logging.getLogger("leonav.orbits")


class StaleEopWarning(UserWarning):
    """The EOP values used are long-range predictions or lie outside the table."""


@dataclass(frozen=True)
class EopValues:
    """EOP at the requested times: UT1-UTC (s) and polar motion x_p, y_p (rad) per time,
    whether each value is a prediction, and where the table came from."""

    ut1_utc_s: np.ndarray
    xp_rad: np.ndarray
    yp_rad: np.ndarray
    predicted: np.ndarray
    source: str


@dataclass(frozen=True)
class EopTable:
    """Daily IERS rows (Bulletin A): MJD (UTC), UT1-UTC (s), x_p, y_p (arcsec), measured flag."""

    mjd: np.ndarray
    ut1_utc_s: np.ndarray
    xp_arcsec: np.ndarray
    yp_arcsec: np.ndarray
    measured: np.ndarray
    source: str
    rejected_lines: int = 0

    @classmethod
    def load(cls, path: str | Path | None = None) -> "EopTable":
        """Read a `finals2000A.all`-format file (default: `$LEONAV_EOP_FILE`, else the
        table of the installed `astropy-iers-data`)."""
        path = Path(path) if path is not None else default_path()
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise UserInputError(f"{path}: cannot read the EOP table ({exc.strerror or exc})") from None
        folder = cache_dir() if len(data) >= CACHE_MIN_BYTES else None
        key = cache_key(data) if folder is not None else ""
        if folder is not None:
            table = _cache_lookup(folder, key, str(path))
            if table is not None:
                return table
        table = cls.parse(data.decode("ascii", errors="replace"), str(path))
        if folder is not None:
            _cache_store(folder, key, table)
        return table

    @classmethod
    def parse(cls, text: str, source: str) -> "EopTable":
        """Parse finals2000A fixed columns: MJD 8-15, PM flag 17, x_p 19-27, y_p 38-46,
        UT1 flag 58, UT1-UTC 59-68 (1-based, inclusive). Rows without UT1-UTC end the table
        (the file's tail has dates only); malformed rows are counted and skipped."""
        rows, rejected = [], 0
        for line in text.splitlines():
            if len(line) < 68 or not line[58:68].strip():
                continue
            try:
                rows.append((float(line[7:15]), float(line[58:68]), float(line[18:27]), float(line[37:46]),
                             line[57] == "I"))
            except ValueError:
                rejected += 1
        if len(rows) < 2:
            raise UserInputError(f"{source}: no EOP rows (expected the IERS finals2000A format: MJD in columns "
                                 "8-15, UT1-UTC in 59-68)")
        a = np.array([r[:4] for r in rows], dtype=float)
        order = np.argsort(a[:, 0], kind="stable")
        if np.any(np.diff(a[order, 0]) <= 0):
            raise UserInputError(f"{source}: duplicated MJD rows in the EOP table")
        measured = np.array([r[4] for r in rows], bool)[order]
        return cls(a[order, 0], a[order, 1], a[order, 2], a[order, 3], measured, source, rejected)

    @property
    def last_measured_mjd(self) -> float:
        """MJD of the last measured (not predicted) UT1-UTC value."""
        return float(self.mjd[self.measured][-1]) if self.measured.any() else float(self.mjd[0])

    def at_mjd(self, mjd_utc: np.ndarray | float, warn: bool = True) -> EopValues:
        """EOP at UTC MJDs (fractional), interpolated linearly between the daily rows."""
        mjd = np.atleast_1d(np.asarray(mjd_utc, dtype=float))
        if not np.all(np.isfinite(mjd)):
            raise UserInputError("EOP requested at a non-finite time")
        # unwrap leap seconds: UT1-UTC jumps by +1 s at the start of the day after a leap second
        steps = np.round(np.diff(self.ut1_utc_s))
        leaps = np.concatenate([[0.0], np.cumsum(steps)])
        smooth = self.ut1_utc_s - leaps
        day = np.clip(np.searchsorted(self.mjd, mjd, side="right") - 1, 0, self.mjd.size - 1)
        ut1 = np.interp(mjd, self.mjd, smooth) + leaps[day]
        xp = np.interp(mjd, self.mjd, self.xp_arcsec) * ARCSEC_RAD
        yp = np.interp(mjd, self.mjd, self.yp_arcsec) * ARCSEC_RAD
        predicted = mjd > self.last_measured_mjd
        if warn:
            self._warn_if_stale(mjd)
        return EopValues(ut1, xp, yp, predicted, self.source)

    def at(self, epoch_utc: _dt.datetime, t_s: np.ndarray | float = 0.0, warn: bool = True) -> EopValues:
        """EOP at `epoch_utc` + t_s (s)."""
        return self.at_mjd(mjd_utc(epoch_utc) + np.asarray(t_s, dtype=float) / 86400.0, warn=warn)

    def _warn_if_stale(self, mjd: np.ndarray) -> None:
        lo, hi = float(mjd.min()), float(mjd.max())
        if lo < self.mjd[0] or hi > self.mjd[-1]:
            warnings.warn(
                f"EOP requested for MJD {lo:.1f}..{hi:.1f}, outside the table {self.source} "
                f"(MJD {self.mjd[0]:.0f}..{self.mjd[-1]:.0f}): the nearest row's values are used; update it "
                "(pip install -U astropy-iers-data)", StaleEopWarning, stacklevel=3)
        elif hi - self.last_measured_mjd > PREDICTION_STALE_DAYS:
            warnings.warn(
                f"EOP for MJD {hi:.1f} are IERS predictions {hi - self.last_measured_mjd:.0f} days past the last "
                f"measured value (MJD {self.last_measured_mjd:.0f}) of {self.source}; UT1-UTC predictions drift by "
                "~1 ms per month (update: pip install -U astropy-iers-data)", StaleEopWarning, stacklevel=3)


def mjd_utc(epoch_utc: _dt.datetime) -> float:
    """UTC Modified Julian Date of an aware (or naive = UTC) datetime."""
    if epoch_utc.tzinfo is None:
        epoch_utc = epoch_utc.replace(tzinfo=_dt.timezone.utc)
    return MJD_UNIX_EPOCH + epoch_utc.timestamp() / 86400.0


def mjd_to_utc(mjd: float) -> _dt.datetime:
    """Aware UTC datetime of a UTC Modified Julian Date."""
    return _dt.datetime.fromtimestamp((float(mjd) - MJD_UNIX_EPOCH) * 86400.0, _dt.timezone.utc)


def default_path() -> Path:
    """`$LEONAV_EOP_FILE`, else the finals2000A table of the installed astropy-iers-data."""
    env = os.environ.get(ENV_FILE)
    if env:
        return Path(env)
    try:
        import astropy_iers_data
    except ImportError:  # pragma: no cover - a declared dependency
        raise UserInputError("no EOP table: install astropy-iers-data or set LEONAV_EOP_FILE to a "
                             "finals2000A.all file") from None
    return Path(astropy_iers_data.IERS_A_FILE)


def cache_dir() -> Path | None:
    """The parsed-table cache folder, or None when `$LEONAV_EOP_CACHE` is `off`."""
    env = os.environ.get(CACHE_ENV, "")
    if env.lower() in ("off", "0", "no", "false"):
        return None
    if env:
        return Path(env)
    root = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(root) / "leonav" / "eop"


def cache_key(data: bytes) -> str:
    """SHA-256 (hex) of the cache format, this module's source (the parser) and the table's bytes."""
    h = hashlib.sha256(f"eop-cache {CACHE_FORMAT}\0".encode())
    h.update(Path(__file__).read_bytes() + b"\0")
    h.update(data)
    return h.hexdigest()


_CACHED_FIELDS = ("mjd", "ut1_utc_s", "xp_arcsec", "yp_arcsec")


def _cache_lookup(folder: Path, key: str, source: str) -> EopTable | None:
    """The table parsed before from the same bytes by the same parser, or None (miss or not valid)."""
    path = folder / f"{key}.npz"
    try:
        with np.load(path, allow_pickle=False) as z:
            if str(z["key"]) != key:
                raise ValueError("key differs")
            arrays = [np.array(z[name]) for name in _CACHED_FIELDS]
            measured, rejected = np.array(z["measured"]), int(z["rejected_lines"])
        n = arrays[0].shape
        if len(n) != 1 or n[0] < 2 or any(a.shape != n or a.dtype != np.float64 for a in arrays) \
                or measured.shape != n or measured.dtype != np.bool_ or not np.all(np.diff(arrays[0]) > 0):
            raise ValueError("arrays do not form a table")
    except FileNotFoundError:
        return None
    except (OSError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile) as exc:
        _log.debug("EOP cache entry %s ignored: %s", path, exc)
        return None
    try:
        os.utime(path)   # recently used: pruned last
    except OSError:
        pass
    return EopTable(*arrays, measured, source, rejected)


def _cache_store(folder: Path, key: str, table: EopTable) -> None:
    path = folder / f"{key}.npz"
    tmp = folder / f".{key}.{os.getpid()}.tmp"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with open(tmp, "wb") as fh:
            np.savez(fh, key=np.array(key), measured=table.measured, rejected_lines=np.array(table.rejected_lines),
                     **{name: getattr(table, name) for name in _CACHED_FIELDS})
        os.replace(tmp, path)
        entries = sorted(folder.glob("*.npz"), key=lambda p: p.stat().st_mtime_ns, reverse=True)
        for old in entries[CACHE_MAX_ENTRIES:]:
            old.unlink(missing_ok=True)
    except OSError as exc:
        _log.debug("EOP cache not written (%s): %s", path, exc)
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass


@functools.lru_cache(maxsize=4)
def _cached(path: str) -> EopTable:
    return EopTable.load(path)


def default_table() -> EopTable:
    """The EOP table in use (read once per process)."""
    return _cached(str(default_path()))


def table_version() -> str:
    """Version of the astropy-iers-data package providing the table ('' for a user file)."""
    if os.environ.get(ENV_FILE):
        return ""
    try:
        from astropy_iers_data import __version__
    except ImportError:  # pragma: no cover
        return ""
    return str(__version__)
