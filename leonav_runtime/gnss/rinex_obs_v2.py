"""The RINEX 2 part of the observation reader (rinex_obs.py): epoch lines, satellite lists of up to
12 per line, observations 5 per line, event flags; the RINEX 2 observation codes as RINEX 3
signals."""
from __future__ import annotations

import functools
import re

from leonav_runtime.gnss import time as gtime

V2_EPOCH = re.compile(r"^ [ \d]\d [ \d]\d [ \d]\d [ \d]\d [ \d]\d [ \d]\d\.\d{7}  [0-6][ \d]{2}\d")
V2_EVENT = re.compile(r"^ {28}[2-5][ \d]{2}\d")  # event flags 2-5 may leave the epoch blank
# RINEX 2 observation code -> (RINEX 3 signal code, quantity). L/D/S follow the code of
# their band: L1 goes with C/A (1C), L2 with P(Y) (2W), as a RINEX 2 receiver tracks them.
_V2_SIGNAL = {"1": "1C", "2": "2W", "5": "5X", "6": "6X", "7": "7X", "8": "8X"}
_V2_CODE = {"C1": "1C", "P1": "1W", "C2": "2X", "P2": "2W", "C5": "5X", "C6": "6X", "C7": "7X", "C8": "8X"}



@functools.lru_cache(maxsize=None)
def v2_type(obs_type: str, system: str) -> tuple[str, str] | None:
    """(signal, quantity C/L/D/S) of a RINEX 2 observation code; None when unknown."""
    if len(obs_type) != 2 or obs_type[0] not in "CPLDS":
        return None
    if obs_type[0] in "CP":
        sig = _V2_CODE.get(obs_type)
        if sig and system == "E":
            sig = sig[0] + "X"
        return (sig, "C") if sig else None
    sig = _V2_SIGNAL.get(obs_type[1])
    if sig and system == "E":
        sig = sig[0] + "X"
    return (sig, obs_type[0]) if sig else None


def read_body(self, i: int) -> None:
    """The epochs of a RINEX 2 body from line index i into the reader `self` (rinex_obs._Reader)."""
    lines, n = self.lines, len(self.lines)
    while i < n:
        line = lines[i]
        if not line.strip():
            i += 1
            continue
        if V2_EVENT.match(line):
            flag, nsat = int(line[28]), int(line[29:32])
            self.counts[f"event_flag_{flag}"] += 1
            i += 1 + nsat
            continue
        if not V2_EPOCH.match(line):
            self.reject(i, "epoch", "expected an epoch line (' yy mm dd hh mm ss.sssssss  f nnn'); "
                        "skipped to the next epoch")
            i = next_epoch(self.lines, i + 1)
            continue
        try:
            yy, mo, dd, hh, mi = (int(line[1 + 3 * k:3 + 3 * k]) for k in range(5))
            sec = float(line[15:26])
            flag = int(line[28])
            nsat = int(line[29:32])
            t = self.to_gps(gtime.calendar_to_seconds(yy + (1900 if yy >= 80 else 2000), mo, dd, hh, mi, sec))
        except ValueError as exc:
            self.reject(i, "epoch", f"unreadable epoch ({exc})")
            i = next_epoch(self.lines, i + 1)
            continue
        if 2 <= flag <= 5:
            self.counts[f"event_flag_{flag}"] += 1
            for k in range(i + 1, min(n, i + 1 + nsat)):
                label = lines[k][60:].strip()
                if label in ("# / TYPES OF OBSERV",):
                    self._header_line(k, lines[k], label, None)
            i += 1 + nsat
            continue
        sats = []
        j = i
        while len(sats) < nsat:
            chunk = lines[j][32:68] if j < n else ""
            take = min(12, nsat - len(sats))
            seg = chunk[:3 * take].ljust(3 * take)
            # 'Gnn' ids; a blank letter is the file's system, a blank tens digit a 0 ("G 5" -> "G05")
            letters = seg[0::3]
            if not letters.isalpha():
                letters = "".join(c if c.strip() else self.file_system for c in letters)
            ids = [a + b + c for a, b, c in zip(letters, seg[1::3].replace(" ", "0"), seg[2::3].replace(" ", "0"))]
            if j > i and (j >= n or lines[j][:32].strip()):
                break
            sats += ids
            j += 1
        if nsat == 0:   # an epoch of no satellite: its line alone (the loop above read none)
            j = i + 1
        if len(sats) != nsat:
            self.reject(i, "satellite list", f"{len(sats)} of {nsat} satellite ids; epoch skipped")
            i = next_epoch(self.lines, j)
            continue
        if flag == 6:
            self.counts["cycle_slip_records"] += 1
        keep = flag == 6 or nsat == 0 or self.new_epoch(t, i)   # an empty epoch holds no time: nothing to repeat
        ntypes = len(self.types_v2)
        per_sat = max(1, -(-ntypes // 5))
        i = j
        need = nsat * per_sat
        # the first line of the next epoch among the satellite lines (or the end of the file) cuts
        # the epoch: the satellites before it are read, the rest dropped
        cut = next((k for k, b in enumerate(lines[i:i + need]) if V2_EPOCH.match(b)), min(need, n - i))
        complete = cut == need
        n_ok = cut // per_sat
        if n_ok:
            self.add_epoch(t, sats[:n_ok], list(range(i, i + n_ok * per_sat, per_sat)),
                           dict.fromkeys({x[0] for x in sats[:n_ok]}, self.types_v2),
                           flag != 6 and keep, flag == 1)
        if not complete:
            self.reject(i + cut, f"observations of {sats[n_ok].strip() or '?'}",
                        "satellite block cut short (end of file or next epoch); rest of the epoch dropped")
        i += cut
        if keep:
            self.counts["epochs" if flag != 6 else "cycle_slip_epochs"] += 1 if complete or flag != 6 else 0

def next_epoch(lines: list[str], i: int) -> int:
    """Index of the next RINEX 2 epoch or event line at or after i."""
    while i < len(lines) and not (V2_EPOCH.match(lines[i]) or V2_EVENT.match(lines[i])):
        i += 1
    return i
