"""GNSS observation rows -> inputs of the generated GNSS observables (no equations here).

For every satellite and epoch of an observation table one code signal is taken (the first
of `PRIMARY_SIGNALS` the satellite has with a pseudorange), its satellite state at transmit
time is computed from the broadcast ephemeris (`sat_states`), and the aux vector of the
generated `GNSS_PSEUDORANGE` / `GNSS_RANGE_RATE` models is filled (layout: `gen/state_layout`
`AUX_*`; meaning: docs/design.md, "Auxiliary measurement input"):

* `r_S_ecef`, `v_S_ecef`: satellite position and velocity at transmit time (ECEF of that epoch)
* `sat_clock`: c (clock + relativistic term - group delay of the signal), c clock drift
* `t_sod`: GPS time of day of reception; `klobuchar`: the 8 broadcast coefficients
* `iono_scale`: (f_L1 / f)^2 when the ionosphere is corrected, else 0; `tropo_scale`: 1 / 0
* `isb_select`: [Galileo, BeiDou] (GPS and QZSS use the GPS clock)

Rows that cannot be used get a status (and a count) instead: `REASONS`. The measurement
variance of a pseudorange is RTKLIB's default error model (`pseudorange_variance`, constants
PR_ERR_* in `gen/constants.py`); it needs the elevation and the ionosphere delay, which the
generated `leonav_gnss_terms` gives.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from leonav.hardware.gnss.lnav import URA_UPPER_M, ura_index
from leonav_runtime.gen import constants as K
from leonav_runtime.gen import state_layout as L
from leonav_runtime.gnss.ephemeris import NO_EPHEMERIS, OK, STALE, UNHEALTHY, Ephemerides
from leonav_runtime.gnss.observations import ObservationTable
from leonav_runtime.gnss.sat_states import NO_PSEUDORANGE, states_for_observations
from leonav_runtime.orbits.broadcast import signal_frequency_hz

# Code signal used per system, in order of preference (RINEX 3 codes; RINEX 2 C1 -> 1C, P1 -> 1W)
PRIMARY_SIGNALS = {
    "G": ("1C", "1W", "1P", "1X", "1S", "1L"),
    "J": ("1C", "1X", "1S", "1L"),
    "E": ("1C", "1X", "1B", "1A"),
    "C": ("2I", "2X", "1P", "1D", "1X"),
}
SYSTEM_NAMES = {"G": "GPS", "E": "Galileo", "C": "BDS", "J": "QZSS"}
ISB_INDEX = {"E": 0, "C": 1}  # which inter-system bias state a system's signals carry

# row status (0 = usable); 1-4 from the ephemeris selection / satellite states
CN0_MASK, URA_TOO_LARGE, OTHER_SIGNAL, SYSTEM_OFF = 5, 6, 7, 8
BELOW_MASK, RAIM_EXCLUDED, EPOCH_UNSOLVED, IMPLAUSIBLE = 9, 10, 11, 12   # 9-12 from `spp.solve`
REASONS = {NO_EPHEMERIS: "no_ephemeris", STALE: "stale_ephemeris", UNHEALTHY: "unhealthy",
           NO_PSEUDORANGE: "no_pseudorange", CN0_MASK: "below_cn0_mask", URA_TOO_LARGE: "ura_too_large",
           OTHER_SIGNAL: "other_signal", SYSTEM_OFF: "system_not_used", BELOW_MASK: "below_elevation_mask",
           RAIM_EXCLUDED: "raim_excluded", EPOCH_UNSOLVED: "epoch_without_solution",
           IMPLAUSIBLE: "implausible_pseudorange"}
MAX_URA_M = 300.0
"""Satellites whose URA exceeds this are not used (RTKLIB's MAX_VAR_EPH = 300^2 m^2)."""
URA_UNKNOWN_M = 8192.0
"""URA of index 15 (no accuracy prediction): not used, beyond MAX_URA_M."""


def klobuchar_coefficients(iono: dict | None) -> np.ndarray | None:
    """alpha0..3, beta0..3 from a navigation header's ION ALPHA/BETA (RINEX 2: GPSA/GPSB
    entries of `NavFile.iono`, RINEX 3 IONOSPHERIC CORR GPSA/GPSB), or None."""
    if not iono or "GPSA" not in iono or "GPSB" not in iono:
        return None
    c = np.r_[np.asarray(iono["GPSA"], float)[:4], np.asarray(iono["GPSB"], float)[:4]]
    return c if c.size == 8 and np.all(np.isfinite(c)) and np.any(c != 0.0) else None


def load_nav_files(paths) -> tuple[Ephemerides, np.ndarray | None]:
    """(ephemerides, Klobuchar coefficients of the first file that has them, or None) of RINEX
    navigation files."""
    from leonav_runtime.gnss.rinex_nav import read_rinex_nav

    eph, klob = Ephemerides.empty(), None
    for p in paths:
        nf = read_rinex_nav(p)
        eph = eph.concat(nf.ephemerides)
        if klob is None:
            klob = klobuchar_coefficients(nf.iono)
    return eph.deduplicate(), klob


def ura_m(eph_rows: np.ndarray) -> np.ndarray:
    """User range accuracy (m) of ephemeris rows as the error model uses it: GPS/QZSS the upper
    bound of the URA class (IS-GPS-200 20.3.3.3.1.3; 8192 m for index 15), Galileo SISA and
    BeiDou URA as broadcast."""
    acc = np.asarray(eph_rows["accuracy_m"], dtype=float)
    gps = np.isin(eph_rows["system"], ("G", "J"))
    idx = np.array([ura_index(float(a)) for a in acc[gps]], dtype=int)
    out = acc.copy()
    out[gps] = np.where(idx < len(URA_UPPER_M), np.asarray(URA_UPPER_M)[np.minimum(idx, len(URA_UPPER_M) - 1)],
                        URA_UNKNOWN_M)
    out[~np.isfinite(out) | (out <= 0)] = URA_UNKNOWN_M
    return out


def pseudorange_variance(el_rad, ura, iono_m, iono_on: bool, tropo_on: bool) -> np.ndarray:
    """RTKLIB's default code variance (m^2): a^2 + b^2 / sin(el) + URA^2 + code bias^2
    + ionosphere (5 m without correction, 0.5 x the Klobuchar delay with) + troposphere (3 m
    without, 0.3 m / (sin el + 0.1) with Saastamoinen). Constants PR_ERR_*."""
    s = np.sin(np.maximum(el_rad, 1e-3))
    var = K.PR_ERR_A_M**2 + K.PR_ERR_B_M**2 / s + np.asarray(ura) ** 2 + K.PR_ERR_CODE_BIAS_M**2
    var = var + ((K.PR_ERR_BRDC_IONO_FACTOR * np.asarray(iono_m)) ** 2 if iono_on else K.PR_ERR_IONO_OFF_M**2)
    var = var + ((K.PR_ERR_SAAS_M / (s + 0.1)) ** 2 if tropo_on else K.PR_ERR_TROPO_OFF_M**2)
    return var


def filter_pseudorange_variance(el_rad, iono_m, iono_on: bool, tropo_on: bool) -> np.ndarray:
    """R (m^2) of a pseudorange record in the filters (GNSS-only EKF, tightly coupled modes):
    (a + b / sin el)^2 with RTKLIB's default code factors a = b = PR_ERR_A_M / PR_ERR_B_M, plus
    the same ionosphere and troposphere residual terms as `pseudorange_variance`. No URA and
    no code-bias term: both are errors of one satellite that hold for hours (broadcast orbit
    and clock over the fit interval, the satellite's group delay), not white noise from epoch
    to epoch; as white R they would be averaged away by a filter that cannot average them, and
    the URA bound (2.4 m for every healthy GPS satellite) flattens the elevation weighting.
    Measured on GEONET 0759/3040 (docs/gnss.md, "GNSS-only EKF"): residual RMS 0.4-0.5 m above
    20 deg, 2.3-2.4 m at 10-15 deg, where RTKLIB's snapshot model gives 3.1 vs 4.7 m."""
    s = np.sin(np.maximum(el_rad, 1e-3))
    var = (K.PR_ERR_A_M + K.PR_ERR_B_M / s) ** 2
    var = var + ((K.PR_ERR_BRDC_IONO_FACTOR * np.asarray(iono_m)) ** 2 if iono_on else K.PR_ERR_IONO_OFF_M**2)
    var = var + ((K.PR_ERR_SAAS_M / (s + 0.1)) ** 2 if tropo_on else K.PR_ERR_TROPO_OFF_M**2)
    return var


@dataclass
class GnssRows:
    """One row per satellite signal and epoch (time-ordered), ready for the generated models.

    t_gps_s, system, prn, signal, sat ("G07"), pseudorange_m (z of GNSS_PSEUDORANGE),
    range_rate_mps (z of GNSS_RANGE_RATE: -lambda D; NaN without Doppler), cn0_dbhz, ura_m,
    aux (n, NAUX), status (0 usable, else a REASONS code), obs_row (row of the source table),
    counts (rows by reason), iono_on / tropo_on (what aux switches on)."""

    t_gps_s: np.ndarray
    system: np.ndarray
    prn: np.ndarray
    signal: np.ndarray
    pseudorange_m: np.ndarray
    range_rate_mps: np.ndarray
    cn0_dbhz: np.ndarray
    ura_m: np.ndarray
    aux: np.ndarray
    status: np.ndarray
    obs_row: np.ndarray
    iono_on: bool
    tropo_on: bool
    klobuchar: np.ndarray | None
    counts: Counter = field(default_factory=Counter)

    def __len__(self) -> int:
        return self.t_gps_s.size

    @property
    def sat(self) -> np.ndarray:
        """'G07'-style names (computed once)."""
        cached = self.__dict__.get("_sat")
        if cached is None or cached.size != self.t_gps_s.size:
            cached = np.array([f"{s}{p:02d}" for s, p in zip(self.system.tolist(), self.prn.tolist())], dtype="U4")
            self.__dict__["_sat"] = cached
        return cached

    def take(self, index) -> "GnssRows":
        cols = {n: getattr(self, n)[index] for n in ("t_gps_s", "system", "prn", "signal", "pseudorange_m",
                                                     "range_rate_mps", "cn0_dbhz", "ura_m", "aux", "status",
                                                     "obs_row")}
        return GnssRows(**cols, iono_on=self.iono_on, tropo_on=self.tropo_on, klobuchar=self.klobuchar,
                        counts=Counter(self.counts))


def primary_rows(obs: ObservationTable, systems: str) -> tuple[np.ndarray, Counter]:
    """Row indices of the signal used for each (epoch, satellite): the first of PRIMARY_SIGNALS
    with a pseudorange, else the first it has at all (so that a missing pseudorange is counted
    once per satellite). Counts rows of other signals and of systems not used."""
    counts: Counter = Counter()
    n = len(obs)
    rank = np.full(n, 99, dtype=int)
    for sys_letter, codes in PRIMARY_SIGNALS.items():
        is_sys = obs.system == sys_letter
        for k, code in enumerate(codes):
            rank[is_sys & (obs.signal == code)] = k
    in_system = np.isin(obs.system, list(systems)) & np.isin(obs.system, list(PRIMARY_SIGNALS))
    counts["system_not_used"] = int((~in_system).sum())
    cand = np.flatnonzero(in_system & (rank < 99))
    # prefer rows with a pseudorange, then the signal rank
    has_pr = np.isfinite(obs.pseudorange_m[cand])
    key_sat = np.char.add(obs.system[cand], np.char.zfill(obs.prn[cand].astype(str), 3))
    order = np.lexsort((rank[cand], ~has_pr, key_sat, obs.t_gps_s[cand]))
    cand = cand[order]
    first = np.ones(cand.size, bool)
    if cand.size > 1:
        same = (obs.t_gps_s[cand][1:] == obs.t_gps_s[cand][:-1]) & (key_sat[order][1:] == key_sat[order][:-1])
        first[1:] = ~same
    chosen = np.sort(cand[first])
    counts["other_signal"] = int(in_system.sum() - chosen.size)
    return chosen, counts


def gnss_rows(obs: ObservationTable, eph: Ephemerides, *, klobuchar: np.ndarray | None, iono: bool = True,
              tropo: bool = True, systems: str = "GEJC", cn0_mask_dbhz: float = 0.0,
              allow_unhealthy: bool = False) -> GnssRows:
    """Inputs of the GNSS observables for the primary signal of every satellite and epoch.

    klobuchar: the 8 broadcast ionosphere coefficients (None: the ionosphere is not corrected,
    counted as 'no_klobuchar_coefficients'); iono / tropo switch the model terms on;
    systems: letters of the constellations used; cn0_mask_dbhz: rows with a C/N0 below it are
    not used (rows without C/N0, e.g. RINEX 2 files without S1, pass).
    """
    rows, counts = primary_rows(obs, systems)
    o = obs.take(rows)
    n = len(o)
    st = states_for_observations(o, eph, allow_unhealthy=allow_unhealthy)
    status = st.status.astype(np.int16)
    ura = np.full(n, np.nan)
    ok = status == OK
    if ok.any():
        ura[ok] = ura_m(eph.data[st.index[ok]])
    status[ok & (ura > MAX_URA_M)] = URA_TOO_LARGE
    low_cn0 = np.isfinite(o.cn0_dbhz) & (o.cn0_dbhz < cn0_mask_dbhz)
    status[(status == OK) & low_cn0] = CN0_MASK
    iono_on = bool(iono and klobuchar is not None)
    if iono and klobuchar is None:
        counts["no_klobuchar_coefficients"] = 1
    f_hz = signal_frequency_hz(o.system, o.signal)
    aux = np.zeros((n, L.NAUX))
    aux[:, L.AUX_R_S_ECEF_SLICE] = st.r_ecef_m
    aux[:, L.AUX_V_S_ECEF_SLICE] = st.v_ecef_mps
    aux[:, L.AUX_SAT_CLOCK] = K.C_LIGHT_MPS * st.clock_s
    aux[:, L.AUX_SAT_CLOCK + 1] = K.C_LIGHT_MPS * st.clock_drift_sps
    aux[:, L.AUX_T_SOD] = np.mod(o.t_gps_s, 86400.0)
    aux[:, L.AUX_IONO_SCALE] = (K.GPS_L1_HZ / f_hz) ** 2 if iono_on else 0.0
    aux[:, L.AUX_TROPO_SCALE] = 1.0 if tropo else 0.0
    for letter, k in ISB_INDEX.items():
        aux[:, L.AUX_ISB_SELECT + k] = o.system == letter
    if klobuchar is not None:
        aux[:, L.AUX_KLOBUCHAR_SLICE] = klobuchar
    status[(status == OK) & ~np.all(np.isfinite(aux), axis=1)] = NO_EPHEMERIS  # e.g. a band without frequency
    with np.errstate(invalid="ignore", divide="ignore"):
        range_rate = -K.C_LIGHT_MPS / f_hz * o.doppler_hz
    for code, name in REASONS.items():
        c = int((status == code).sum())
        if c:
            counts[name] = c
    counts["usable"] = int((status == OK).sum())
    return GnssRows(o.t_gps_s, o.system, o.prn, o.signal, o.pseudorange_m, range_rate, o.cn0_dbhz, ura, aux,
                    status, rows, iono_on, bool(tropo), klobuchar, counts)
