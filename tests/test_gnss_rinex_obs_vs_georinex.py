"""RINEX observation reader against georinex (an independent reader) on real files the GEONET
set does not cover:

* tests/data/rinex/delf0010_cut.21o: RINEX 2.11 as IGS/EUREF stations write it (teqc): 7
  observation types (L1 L2 C1 P2 P1 S1 S2, so every satellite takes two lines), 20
  satellites an epoch (the satellite list continues on a second line), GPS + GLONASS,
  LLI 4 (anti-spoofing) on L2 and SSI on the phases only;
* tests/data/rinex/LARM0010.22O: RINEX 3.04 with Doppler, SSI digits and two LLI 1 (loss of
  lock) flags.

Every value, LLI and SSI digit georinex reads must be in our table, on the signal and
quantity the RINEX 2 -> 3 mapping gives (rinex_obs_v2.py), and our flags must be the LLI
bits. Sources: tests/data/README.md.
"""
from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from leonav_runtime.gnss.observations import FLAG_ANTISPOOFING, FLAG_HALF_CYCLE, FLAG_LOSS_OF_LOCK
from leonav_runtime.gnss.rinex_obs import read_rinex_obs

gr = pytest.importorskip("georinex")

DATA = Path(__file__).parent / "data" / "rinex"
DELF = DATA / "delf0010_cut.21o"
LARM = DATA / "LARM0010.22O"
GPS_EPOCH = np.datetime64("1980-01-06T00:00:00", "ns")
QUANTITY_COLUMN = {"C": "pseudorange_m", "L": "carrier_phase_cyc", "D": "doppler_hz", "S": "cn0_dbhz"}
# RINEX 2 code -> (signal, quantity) as documented in rinex_obs_v2.py
V2 = {"C1": ("1C", "C"), "P1": ("1W", "C"), "P2": ("2W", "C"), "L1": ("1C", "L"), "L2": ("2W", "L"),
      "S1": ("1C", "S"), "S2": ("2W", "S")}


def _georinex(path: Path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # xarray FutureWarnings inside georinex
        return gr.load(path, useindicators=True)


def _ours(path: Path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")    # no rejected line in these files
        return read_rinex_obs(path)


def _index(obs) -> dict:
    return {(float(t), f"{s}{p:02d}", sig): k for k, (t, s, p, sig) in
            enumerate(zip(obs.t_gps_s, obs.system, obs.prn, obs.signal))}


def _reference(path: Path, mapping) -> list[tuple]:
    """(t_gps_s, sat, signal, quantity, value, lli, ssi) of every value georinex reads."""
    ds = _georinex(path)
    t_gps = (ds.time.values.astype("datetime64[ns]") - GPS_EPOCH) / np.timedelta64(1, "s")
    out = []
    for code in [v for v in ds.data_vars if not v.endswith(("lli", "ssi"))]:
        sig_qty = mapping(code)
        if sig_qty is None:
            continue
        val = ds[code].values
        lli = ds[code + "lli"].values if code + "lli" in ds else np.full(val.shape, np.nan)
        ssi = ds[code + "ssi"].values if code + "ssi" in ds else np.full(val.shape, np.nan)
        for i, j in zip(*np.nonzero(np.isfinite(val))):
            out.append((float(t_gps[i]), str(ds.sv.values[j]), *sig_qty, float(val[i, j]),
                        0 if math.isnan(lli[i, j]) else int(lli[i, j]), 0 if math.isnan(ssi[i, j]) else int(ssi[i, j])))
    return out


def _v3_mapping(code: str):
    return (code[1:3], code[0]) if len(code) == 3 and code[0] in "CLDS" else None


@pytest.mark.parametrize("path,mapping,n_values,n_rows", [(DELF, V2.get, 4 * 20 * 7 - 0, 240),
                                                            (LARM, _v3_mapping, None, 216)])
def test_every_value_lli_and_ssi_georinex_reads(path, mapping, n_values, n_rows):
    obs = _ours(path)
    ref = _reference(path, mapping)
    assert len(obs) == n_rows and obs.counts["epochs"] == 4
    if n_values is not None:
        assert len(ref) == n_values   # all 7 types of all 20 satellites of the 4 epochs are present
    where = _index(obs)
    lli_phase, ssi_code, ssi_phase = {}, {}, {}
    for t, sat, sig, qty, value, lli, ssi in ref:
        k = where.get((t, sat, sig))
        assert k is not None, f"{path.name}: {sat} {sig} at {t} missing"
        ours = getattr(obs, QUANTITY_COLUMN[qty])[k]
        assert ours == pytest.approx(value, rel=1e-12, abs=1e-9), (path.name, sat, sig, qty)
        if qty == "L":
            lli_phase[k], ssi_phase[k] = lli, ssi
        elif qty == "C":
            ssi_code[k] = ssi
    for k, lli in lli_phase.items():
        assert obs.lli[k] == lli
        flags = int(obs.flags[k])
        assert bool(flags & FLAG_LOSS_OF_LOCK) == bool(lli & 1)
        assert bool(flags & FLAG_HALF_CYCLE) == bool(lli & 2)
        assert bool(flags & FLAG_ANTISPOOFING) == bool(lli & 4)
    # SSI of a row: the code's when it has one, else the phase's (RINEX 2: only phases carry it)
    for k in set(ssi_code) | set(ssi_phase):
        assert obs.ssi[k] == (ssi_code.get(k) or ssi_phase.get(k, 0)), k


def test_rinex2_seven_types_two_lines_per_satellite():
    obs = _ours(DELF)
    # first satellite of the file: G07, line 1 "126298057.858 6  98414080.64743  24033720.416 ..."
    # line 2 "40.000          22.0004" (S1, S2 on the continuation line)
    g07 = np.flatnonzero((obs.system == "G") & (obs.prn == 7) & (obs.t_gps_s == obs.t_gps_s[0]))
    by_signal = {obs.signal[k]: k for k in g07}
    assert set(by_signal) == {"1C", "2W", "1W"}
    k1, k2, kp = by_signal["1C"], by_signal["2W"], by_signal["1W"]
    assert obs.carrier_phase_cyc[k1] == 126298057.858 and obs.ssi[k1] == 6 and obs.lli[k1] == 0
    assert obs.carrier_phase_cyc[k2] == 98414080.647 and obs.lli[k2] == 4 and obs.ssi[k2] == 3
    assert obs.pseudorange_m[k1] == 24033720.416 and obs.pseudorange_m[k2] == 24033721.351
    assert obs.pseudorange_m[kp] == 24033719.353
    assert obs.cn0_dbhz[k1] == 40.0 and obs.cn0_dbhz[k2] == 22.0
    assert obs.flags[k2] & FLAG_ANTISPOOFING and not obs.flags[k1] & FLAG_ANTISPOOFING
    # 12 GPS + 8 GLONASS satellites in every epoch, the last 8 from the continuation line
    for t in np.unique(obs.t_gps_s):
        sats = {f"{s}{p:02d}" for s, p in zip(obs.system[obs.t_gps_s == t], obs.prn[obs.t_gps_s == t])}
        assert len(sats) == 20 and {"R18", "G13", "R01", "R16", "R17", "G15", "R02", "R15"} <= sats
