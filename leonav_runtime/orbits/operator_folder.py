"""A folder of operator ephemerides read satellite by satellite, as a stream meets them.

A live run (`leonav nav --operator-ephemerides DIR`) does not know in advance which Starlink
satellites it will measure, and a full folder holds ~10,000 files: `OperatorFolder` checks the
folder once (it exists and lists files), then reads a satellite's file the first time that
satellite is measured (`ensure`), into one `OperatorEphemerisSet` that grows. Each name is
tried once; a satellite without a file, or whose file is refused, is counted, and its
measurements keep their element-set states (the rule of `replay.beacon_table`).
"""
from __future__ import annotations

import warnings
from pathlib import Path

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.orbits.operator_ephemeris import (
    MANIFEST,
    OperatorEphemerisSet,
    RejectedEphemerisWarning,
    load_folder,
    name_from_filename,
)


class OperatorFolder:
    """The operator files of `folder`, loaded on first use per satellite name."""

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        if not self.folder.is_dir():
            raise UserInputError(f"--operator-ephemerides {folder}: not a folder of operator ephemerides "
                                 f"(expected {MANIFEST} and MEME_*.txt files)")
        manifest = self.folder / MANIFEST
        listed = ([ln.strip() for ln in manifest.read_text(encoding="ascii", errors="replace").splitlines()]
                  if manifest.exists() else [p.name for p in self.folder.glob("*.txt")])
        self.listed = {name_from_filename(e) for e in listed if "/" not in e and "\\" not in e}
        if not self.listed:
            raise UserInputError(f"--operator-ephemerides {folder}: lists no operator-ephemeris file "
                                 f"({MANIFEST} empty or no *.txt)")
        self.set = OperatorEphemerisSet({})
        self._tried: set[str] = set()
        self.ids_to_names: dict[int, str] = {}     # NORAD id -> object name of the satellites met
        self.counts = {"satellites_with_file": 0, "satellites_without_file": 0, "files_refused": 0}

    def files(self, ids_to_names: dict[int, str]) -> OperatorEphemerisSet:
        """The set, after reading the files of these satellites not tried yet (`ensure`): a satellite
        it does not hold keeps its element-set states and is counted so by the tables' `stats`."""
        self.ensure(ids_to_names)
        return self.set

    def ensure(self, ids_to_names: dict[int, str]) -> list[str]:
        """Read the files of the satellites ({NORAD id: object name}, the element sets' names) not
        tried yet; returns the names newly loaded."""
        self.ids_to_names.update({int(i): str(n).strip() for i, n in ids_to_names.items()})
        new = sorted({str(n).strip() for n in ids_to_names.values()} - self._tried)
        if not new:
            return []
        self._tried.update(new)
        wanted = [n for n in new if n in self.listed]
        self.counts["satellites_without_file"] += len(new) - len(wanted)
        loaded: list[str] = []
        if wanted:
            with warnings.catch_warnings():     # refusals are counted here (one line each in `rejected`)
                warnings.simplefilter("ignore", RejectedEphemerisWarning)
                try:
                    got = load_folder(self.folder, names=wanted)
                except UserInputError as exc:   # every wanted file refused
                    got = None
                    self.set.rejected.append((", ".join(wanted), str(exc)))
                except OSError:                 # not readable now (descriptors exhausted...): tried again
                    self._tried.difference_update(wanted)
                    self.counts["read_errors"] = self.counts.get("read_errors", 0) + 1
                    return []
            if got is not None:
                loaded = [n for n in got.ephemerides if n not in self.set.ephemerides]
                self.set.ephemerides.update({n: got.ephemerides[n] for n in loaded})
                # the folder's own refusals (a bad MANIFEST line) come with every read: kept once
                self.set.rejected.extend(r for r in got.rejected if r not in self.set.rejected)
            refused = len(wanted) - len(loaded)
            self.counts["files_refused"] += refused
        self.counts["satellites_with_file"] = len(self.set.ephemerides)
        return loaded
