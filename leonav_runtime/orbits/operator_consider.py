"""The operator's orbit covariance per measurement record, for the consider term of the filter.

`OperatorCovariance` is the provider `inputs.consider.OrbitConsider.covariance` takes: for
records (satellite id, time, satellite state) it returns the ECEF covariance of the
satellite's [r, v] that its operator ephemeris gives at that time (operator_states.py), so
R = sigma^2 + J P_operator J^T instead of the element-age model's J P_model J^T.

Satellites are keyed by NORAD id on the records and by object name in the operator's files;
`names_by_id` joins them (built from the element sets' names, the same STARLINK-nnnnn names).
A differenced observable's reference carries no id on the records: it is recognised as the
covered satellite whose operator position lies nearest the record's reference state (Starlink
satellites in view are tens of km apart or more, the element sets' error is about 1 km), and
only within `match_m`. Records without a covering file are NaN (the caller falls back) and
counted in `uncovered_records`, announced once.
"""
from __future__ import annotations

import datetime as _dt
import hashlib
import warnings
from pathlib import Path

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.orbits.elements import ElementSet
from leonav_runtime.orbits.eop import EopTable
from leonav_runtime.orbits.operator_ephemeris import OperatorEphemerisSet, load_folder
from leonav_runtime.orbits.operator_states import (
    OperatorCoverageWarning,
    operator_states_ecef,
)

_FOLDERS: dict[tuple, OperatorCovariance] = {}


def folder_covariance(folder: str | Path, elements: ElementSet, epoch_utc: _dt.datetime) -> OperatorCovariance:
    """The provider for a scenario: the operator files in `folder` of the satellites of
    `elements` (an `ElementSet`, joined by name), kept per process for the same folder
    content, element names and epoch (every trial of a sweep builds its records with it)."""
    folder = Path(folder)
    listing = tuple(sorted((p.name, p.stat().st_mtime_ns, p.stat().st_size) for p in folder.iterdir() if p.is_file()))
    ids_to_names = names_by_id(elements.norad_ids, elements.names)
    key = (str(folder), listing, tuple(sorted(ids_to_names.items())), epoch_utc.isoformat())
    if key not in _FOLDERS:
        _FOLDERS.clear()    # one folder at a time: bounded memory
        # only the scenario's satellites are read; refused files are counted and said once (load_folder)
        ephemerides = load_folder(folder, names=sorted(set(ids_to_names.values())))
        _FOLDERS[key] = OperatorCovariance(ephemerides, epoch_utc, ids_to_names)
    return _FOLDERS[key]


def names_by_id(norad_ids, names) -> dict[int, str]:
    """{NORAD id: object name} from element-set columns (names stripped)."""
    return {int(i): str(n).strip() for i, n in zip(norad_ids, names)}


_MEMO_ENTRIES = 16   # distinct record sets kept (kinds x satellite counts of a sweep)


class OperatorCovariance:
    """Per-record ECEF covariance (m^2, m^2/s, m^2/s^2) of [r, v] from operator ephemerides;
    times are seconds since `epoch_utc` (UTC), like the records'."""

    def __init__(self, ephemerides: OperatorEphemerisSet, epoch_utc: _dt.datetime, ids_to_names: dict[int, str],
                 *, eop: EopTable | None = None, match_m: float = 50e3, quiet: bool = False) -> None:
        """quiet: records without a covering file are only counted (`uncovered_records`), not
        announced (a caller that makes a provider per record counts them itself)."""
        self.ephemerides = ephemerides
        self.epoch_utc = epoch_utc
        self.ids_to_names = {i: n for i, n in ids_to_names.items() if n in ephemerides.ephemerides}
        self.eop = eop
        self.match_m = match_m
        self.uncovered_records = 0       # per distinct request (repeats come from the memo)
        self._warned = quiet
        self._memo: dict[bytes, np.ndarray] = {}

    def _states(self, names: list[str], t_s: np.ndarray):
        with warnings.catch_warnings():      # partial coverage is counted below, once
            warnings.simplefilter("ignore", OperatorCoverageWarning)
            try:
                return operator_states_ecef(self.ephemerides, names, self.epoch_utc, t_s, eop=self.eop)
            except UserInputError:          # none covered over these times: all NaN
                return None

    def covariance_ecef(self, sat_id: np.ndarray | None, t_s: np.ndarray, state9: np.ndarray) -> np.ndarray:
        """(n, 6, 6) covariance per record; sat_id None: match each record's state (n, 9)
        to the nearest covered satellite. NaN where no file covers the record."""
        t_s = np.asarray(t_s, float)
        digest = hashlib.blake2b(t_s.tobytes(), digest_size=16)
        digest.update(b"state" + np.ascontiguousarray(state9[:, 0:3]).tobytes() if sat_id is None
                      else b"id" + np.asarray(sat_id, np.int64).tobytes())
        key = digest.digest()
        if key in self._memo:            # a sweep's trials ask for the same records again
            return self._memo[key].copy()
        out = self._compute(sat_id, t_s, state9)
        if len(self._memo) >= _MEMO_ENTRIES:
            self._memo.pop(next(iter(self._memo)))
        self._memo[key] = out
        return out.copy()

    def _compute(self, sat_id: np.ndarray | None, t_s: np.ndarray, state9: np.ndarray) -> np.ndarray:
        out = np.full((t_s.size, 6, 6), np.nan)
        if sat_id is None:
            names = sorted(set(self.ids_to_names.values()))
            times, k = np.unique(t_s, return_inverse=True)
            st = self._states(names, times) if names else None
            if st is not None:
                d = np.linalg.norm(st.r_ecef_m[:, k, :] - state9[None, :, 0:3], axis=2)   # (nsat, n)
                d = np.where(np.isfinite(d), d, np.inf)
                best = np.argmin(d, axis=0)
                near = d[best, np.arange(t_s.size)] <= self.match_m
                out[near] = st.cov_ecef[best[near], k[near]]
        else:
            for sid in np.unique(sat_id):
                name = self.ids_to_names.get(int(sid))
                if name is None:
                    continue
                rows = np.flatnonzero(sat_id == sid)
                times, k = np.unique(t_s[rows], return_inverse=True)
                st = self._states([name], times)
                if st is not None:
                    out[rows] = st.cov_ecef[0, k]
        missing = int((~np.isfinite(out).all(axis=(1, 2))).sum())
        self.uncovered_records += missing
        if missing and not self._warned:
            self._warned = True
            warnings.warn(f"operator ephemerides: {missing} of {t_s.size} records have no operator covariance "
                          "(satellite without a file, or outside its span); they keep the element-age model's "
                          "consider term where one is set", OperatorCoverageWarning, stacklevel=2)
        return out
