"""Mutant catalogue, GNSS: rinex obs/nav, spp/signals, broadcast/ephemeris, gnss_ekf/coupled, lnav/sfrbx, orbits/eop.

Same rules as benchmarks/mutants.py: one realistic bug per entry, each edit's text occurs once.
Written before the tests that target them (issue 24), aimed at what the earlier held-out audit
found untested: RINEX 2 files with more than 5 observation types, receiver clock jumps,
high-eccentricity orbits (Galileo E14/E18, QZSS), ephemerides at the edge of their fit
interval, RAIM at redundancy 1, the LNAV parity beyond encode -> decode, covariance blocks
of the GNSS-only EKF, LLI/SSI flags.
"""
from __future__ import annotations

from mutants import MODULES, mutant  # noqa: F401

MODULES["rinex_obs"] = {"files": ["leonav_runtime/gnss/rinex_obs.py", "leonav_runtime/gnss/rinex_obs_v2.py",
                                  "leonav_runtime/gnss/rinex_obs_fields.py"],
                        "tests": ["tests/test_gnss_rinex_obs_vs_georinex.py", "tests/test_gnss_rinex_obs.py",
                                  "tests/test_gnss_rinex_obs_reference.py", "tests/test_gnss_hostile_rinex.py"]}
MODULES["rinex_nav"] = {"files": ["leonav_runtime/gnss/rinex_nav.py"],
                        "tests": ["tests/test_gnss_eccentric_orbits.py", "tests/test_gnss_rinex_nav.py"]}
MODULES["broadcast"] = {"files": ["leonav_runtime/orbits/broadcast.py", "leonav_runtime/gnss/ephemeris.py"],
                        "tests": ["tests/test_gnss_eccentric_orbits.py", "tests/test_gnss_broadcast.py",
                                  "tests/test_gnss_rtklib.py"]}
MODULES["spp"] = {"files": ["leonav_runtime/gnss/spp.py", "leonav_runtime/gnss/signals.py"],
                  "tests": ["tests/test_gnss_spp_edges.py", "tests/test_spp_bad_input.py", "tests/test_spp.py",
                            "tests/test_gnss_rtklib.py"]}
MODULES["gnss_ekf"] = {"files": ["leonav_runtime/gnss/gnss_ekf.py", "leonav_runtime/gnss/coupled.py"],
                       "tests": ["tests/test_gnss_ekf_outputs.py", "tests/test_gnss_coupled_edges.py",
                                 "tests/test_spp.py", "tests/test_gnss_coupled.py"]}
MODULES["lnav"] = {"files": ["hardware/gnss/lnav.py", "leonav_runtime/gnss/sfrbx.py"],
                   "tests": ["tests/test_gnss_lnav_ublox.py", "tests/test_gnss_lnav.py", "tests/test_gnss_iono_page.py"]}
MODULES["eop"] = {"files": ["leonav_runtime/orbits/eop.py"],
                  "tests": ["tests/test_eop_skyfield.py", "tests/test_eop.py"]}

# ---------------------------------------------------------------- rinex_obs
OBS, OBS2, OBSF = "leonav_runtime/gnss/rinex_obs.py", "leonav_runtime/gnss/rinex_obs_v2.py", "leonav_runtime/gnss/rinex_obs_fields.py"
# re-targeted to the NumPy field reader (rinex_obs_fields.py, d6247de) after the catalogue's first
# run: same bugs, today's code
mutant("rinex_obs-01", OBS2, "RINEX 2: one line per satellite whatever the number of types (floor, not ceiling)",
       ("per_sat = max(1, -(-ntypes // 5))", "per_sat = max(1, ntypes // 5)"))
mutant("rinex_obs-02", OBSF, "LLI and SSI columns not read (fields taken as 14 columns)",
       ("code = np.where(flags < 10, flags, 0).astype(np.int64)", "code = np.zeros(flags.shape, dtype=np.int64)"))
mutant("rinex_obs-03", OBS2, "RINEX 2: continuation line of the satellite list reads 12 ids again",
       ("take = min(12, nsat - len(sats))", "take = min(12, nsat)"))
mutant("rinex_obs-04", OBS2, "RINEX 2: C2 and P2 mapped to each other's signal",
       ('"C2": "2X", "P2": "2W"', '"C2": "2W", "P2": "2X"'))
mutant("rinex_obs-05", OBSF, "LLI taken from the code fields as well as the phase",
       ("                ssi_s = np.where(use & (ssi[:, m] != 0), ssi[:, m], ssi_s)\n",
        "                ssi_s = np.where(use & (ssi[:, m] != 0), ssi[:, m], ssi_s)\n"
        "                lli_s = np.where(use, lli[:, m], lli_s)\n"))
mutant("rinex_obs-06", OBSF, "half-cycle flag read from LLI bit 2 (value 4)",
       ("np.where(lli_s[sel] & 2, FLAG_HALF_CYCLE, 0)", "np.where(lli_s[sel] & 4, FLAG_HALF_CYCLE, 0)"))
mutant("rinex_obs-07", OBSF, "anti-spoofing flag read from LLI bit 0",
       ("np.where(lli_s[sel] & 4, FLAG_ANTISPOOFING, 0)", "np.where(lli_s[sel] & 1, FLAG_ANTISPOOFING, 0)"))
mutant("rinex_obs-08", OBSF, "LLI and SSI columns swapped",
       ("return values, code[..., 0], code[..., 1], blank, plain", "return values, code[..., 1], code[..., 0], blank, plain"))
mutant("rinex_obs-09", OBSF, "SSI of the phase not used when the code field has none",
       ("                ssi_s = np.where(use & (ssi_s == 0), ssi[:, m], ssi_s)\n", ""))
mutant("rinex_obs-10", OBS, "GLONASS (UTC) epochs: leap seconds subtracted",
       ("return t_sys + gtime.leap_seconds_at_gps(t_sys + 18)", "return t_sys - gtime.leap_seconds_at_gps(t_sys + 18)"))
mutant("rinex_obs-11", OBSF, "RINEX 3: observation fields start one column late (NumPy read only)",
       ("wide = \"\".join([ln[3:3 + width].ljust(width) for ln in block])",
        "wide = \"\".join([ln[4:4 + width].ljust(width) for ln in block])"))
# (the same table comes out, every field re-read by the per-field reader: killed by the test that
# clean files take the NumPy path, tests/test_gnss_rinex_obs_reference.py)
mutant("rinex_obs-12", OBSF, "RINEX 3: observation fields start one column late (both readers)",
       ("wide = \"\".join([ln[3:3 + width].ljust(width) for ln in block])",
        "wide = \"\".join([ln[4:4 + width].ljust(width) for ln in block])"),
       ("text = reader.lines[k][3 + 16 * m:3 + 16 * (m + 1)]", "text = reader.lines[k][4 + 16 * m:4 + 16 * (m + 1)]"))

# ---------------------------------------------------------------- rinex_nav
NAV = "leonav_runtime/gnss/rinex_nav.py"
mutant("rinex_nav-01", NAV, "eccentricity range 0..0.1 (rejects Galileo E14/E18, e = 0.16)",
       ('"e": (0.0, 0.5)', '"e": (0.0, 0.1)'))
mutant("rinex_nav-02", NAV, "sqrt(A) range to 6000 m^0.5 (rejects QZSS and BeiDou IGSO/GEO)",
       ('"sqrt_a": (2500.0, 7500.0)', '"sqrt_a": (2500.0, 6000.0)'))
mutant("rinex_nav-03", NAV, "RINEX 3 clock fields read from the RINEX 2 columns",
       ("c0 = 23 if v3 else 22", "c0 = 22"))
mutant("rinex_nav-04", NAV, "Galileo BGD(E1,E5a) and BGD(E1,E5b) swapped",
       ('("accuracy_m", "health", "tgd", "tgd2"),\n                    ("transmit_sow", None, None, None)',
        '("accuracy_m", "health", "tgd2", "tgd"),\n                    ("transmit_sow", None, None, None)'))
mutant("rinex_nav-05", NAV, "BeiDou toc/toe kept in BDT (no +14 s)",
       ('to_gps = gtime.bdt_to_gps_seconds if system == "C" else (lambda t: t)', "to_gps = lambda t: t"))
mutant("rinex_nav-06", NAV, "RINEX 3 IONOSPHERIC CORR read one column early",
       ('tuple(float(line[5 + 12 * k:17 + 12 * k].replace("D", "E") or 0)',
        'tuple(float(line[4 + 12 * k:16 + 12 * k].replace("D", "E") or 0)'))
mutant("rinex_nav-07", NAV, "QZSS fit flag read as GPS fit hours",
       ('elif system == "J":\n        row["fit_flag"] = int(fit_hours != 0)',
        'elif system == "J":\n        row["fit_flag"] = 1 if fit_hours > 4.0 else 0'))
mutant("rinex_nav-08", NAV, "RINEX 2 record start from column 1 only (PRN 1-9 have a blank there)",
       ("return bool(line[:1].strip()) if v3 else bool(line[:2].strip())", "return bool(line[:1].strip())"))
mutant("rinex_nav-09", NAV, "GLONASS records expected with 3 lines",
       ('"R": 4, "S": 4}', '"R": 3, "S": 4}'))
mutant("rinex_nav-10", NAV, "QZSS orbits taken with the Galileo field list",
       ('    "J": _COMMON + (("idot", "codes_l2", "week", "l2p_flag"), ("accuracy_m", "health", "tgd", "iodc"),\n'
        '                    ("transmit_sow", "fit_hours", None, None)),',
        '    "J": _COMMON + (("idot", "data_sources", "week", None), ("accuracy_m", "health", "tgd", "tgd2"),\n'
        '                    ("transmit_sow", None, None, None)),'))

# ---------------------------------------------------------------- broadcast/ephemeris
BRD, EPH = "leonav_runtime/orbits/broadcast.py", "leonav_runtime/gnss/ephemeris.py"
mutant("broadcast-01", BRD, "relativistic clock term subtracted",
       ('bias = rows["af0"] + dt_clk * (rows["af1"] + dt_clk * rows["af2"]) + rel',
        'bias = rows["af0"] + dt_clk * (rows["af1"] + dt_clk * rows["af2"]) - rel'))
mutant("broadcast-02", BRD, "Kepler's equation: 3 Newton iterations at most",
       ("KEPLER_MAX_ITER = 30", "KEPLER_MAX_ITER = 3"))
mutant("broadcast-03", BRD, "sqrt(1 - e^2) to first order in e^2 (small-eccentricity shortcut)",
       ("sq1e2 = np.sqrt(1.0 - e * e)", "sq1e2 = 1.0 - 0.5 * e * e"))
mutant("broadcast-04", BRD, "relativistic term with the mean instead of the eccentric anomaly",
       ('rel = f_rel * e * rows["sqrt_a"] * sin_e', 'rel = f_rel * e * rows["sqrt_a"] * np.sin(mk)'))
mutant("broadcast-05", BRD, "radius rate without the eccentricity factor",
       ("rk_dot = e * a * ek_dot * sin_e", "rk_dot = a * ek_dot * sin_e"))
mutant("broadcast-06", BRD, "BeiDou GEO tilt applied with the wrong sign",
       ("cp * vec[:, 1] + sp * vec[:, 2], -sp * vec[:, 1] + cp * vec[:, 2]",
        "cp * vec[:, 1] - sp * vec[:, 2], sp * vec[:, 1] + cp * vec[:, 2]"))
mutant("broadcast-07", BRD, "GPS L2 group delay without the square of the frequency ratio",
       ("(GPS_L1_HZ / GPS_L2_HZ) ** 2 * tgd", "(GPS_L1_HZ / GPS_L2_HZ) * tgd"))
mutant("broadcast-08", BRD, "Galileo E1: F/NAV and I/NAV BGDs swapped",
       ("e1 = np.where(fnav_clock, tgd, tgd2)", "e1 = np.where(fnav_clock, tgd2, tgd)"))
mutant("broadcast-09", BRD, "Galileo orbits with GPS's mu (3.986005e14 for 3.986004418e14)",
       ("mu = np.where(is_e, GAL_MU_M3PS2,", "mu = np.where(is_e, GPS_MU_M3PS2,"))
mutant("broadcast-10", EPH, "an ephemeris exactly at the edge of its fit interval is stale",
       ("inside = dt <= half[None, :]", "inside = dt < half[None, :]"))
mutant("broadcast-11", EPH, "the whole fit interval taken as the half-width around toe",
       ('d["fit_s"][recs] / 2.0', 'd["fit_s"][recs]'))
mutant("broadcast-12", EPH, "ties in toe go to the earlier transmission",
       ('order = np.lexsort((-transmit, d["toe"], rec_keys))', 'order = np.lexsort((transmit, d["toe"], rec_keys))'))
mutant("broadcast-13", EPH, "QZSS fit flag 0/1 read the wrong way round",
       ("return 2 * 3600.0 if not fit_hours else 4 * 3600.0", "return 4 * 3600.0 if not fit_hours else 2 * 3600.0"))
mutant("broadcast-14", EPH, "BeiDou-3 GEOs (C59-C63) not treated as GEO",
       ("return (prn <= 5) | ((prn >= 59) & (prn <= 63))", "return prn <= 5"))
mutant("broadcast-15", EPH, "unhealthy and stale statuses swapped",
       ("status[qq[~ok & any_inside]] = UNHEALTHY\n                status[qq[~ok & ~any_inside]] = STALE",
        "status[qq[~ok & any_inside]] = STALE\n                status[qq[~ok & ~any_inside]] = UNHEALTHY"))

# ---------------------------------------------------------------- spp/signals
SPP, SIG = "leonav_runtime/gnss/spp.py", "leonav_runtime/gnss/signals.py"
mutant("spp-01", SPP, "RAIM excludes at redundancy 1 (leaves an epoch without a check)",
       ("retry = failing & (dof >= 2)", "retry = failing & (dof >= 1)"))
mutant("spp-02", SPP, "standardised residual without the leverage term",
       ("np.abs(v) / np.sqrt(np.maximum(var - q, 1e-12))", "np.abs(v) / np.sqrt(var)"))
mutant("spp-03", SPP, "HDOP and VDOP swapped",
       ("np.sqrt(d[:, :2].sum(1)), np.sqrt(d[:, 2])]", "np.sqrt(d[:, 2]), np.sqrt(d[:, :2].sum(1))]"))
mutant("spp-04", SPP, "gross-error band without the epoch clock's uncertainty",
       ("<= half + widest[inv])", "<= half)"))
mutant("spp-05", SPP, "gross-error clock as the mean (one gross row pulls it)",
       ("clock[e], widest[e] = np.median(off[m]), half[m].max()", "clock[e], widest[e] = np.mean(off[m]), half[m].max()"))
mutant("spp-06", SPP, "ISB pseudo-observation on the constellations that are present",
       ("N[~present[:, k], j, j] += 1.0 / ISB_PSEUDO_VAR_M2", "N[present[:, k], j, j] += 1.0 / ISB_PSEUDO_VAR_M2"))
mutant("spp-07", SPP, "epoch status: GDOP test dropped",
       ("    status[enough & converged & ~(dop[:, 0] <= opts.max_gdop)] = GDOP_FAILED\n", ""))
mutant("spp-08", SIG, "elevation term of the code variance over sin^2(el)",
       ("K.PR_ERR_B_M**2 / s + np.asarray(ura) ** 2", "K.PR_ERR_B_M**2 / s**2 + np.asarray(ura) ** 2"))
mutant("spp-09", SIG, "QZSS URA not mapped to its class bound",
       ('gps = np.isin(eph_rows["system"], ("G", "J"))', 'gps = np.isin(eph_rows["system"], ("G",))'))
mutant("spp-10", SIG, "URA limit not applied", ("    status[ok & (ura > MAX_URA_M)] = URA_TOO_LARGE\n", ""))
mutant("spp-11", SIG, "GPS P1 preferred over C/A", ('"G": ("1C", "1W", "1P",', '"G": ("1W", "1C", "1P",'))
mutant("spp-12", SIG, "range rate with the sign of the Doppler", ("range_rate = -K.C_LIGHT_MPS / f_hz * o.doppler_hz",
                                                                 "range_rate = K.C_LIGHT_MPS / f_hz * o.doppler_hz"))
mutant("spp-13", SIG, "ionosphere scale (f / f_L1)^2 instead of (f_L1 / f)^2",
       ("(K.GPS_L1_HZ / f_hz) ** 2 if iono_on", "(f_hz / K.GPS_L1_HZ) ** 2 if iono_on"))
mutant("spp-14", SIG, "C/N0 mask applied to rows at the mask value too",
       ("(o.cn0_dbhz < cn0_mask_dbhz)", "(o.cn0_dbhz <= cn0_mask_dbhz)"))

# ---------------------------------------------------------------- gnss_ekf/coupled
EKF_, CPL = "leonav_runtime/gnss/gnss_ekf.py", "leonav_runtime/gnss/coupled.py"
mutant("gnss_ekf-01", EKF_, "position covariance output from the velocity block",
       ("cov[e] = np.diag(res.P_diag[last[e], L.DX_DP_SLICE])", "cov[e] = np.diag(res.P_diag[last[e], L.DX_DV_SLICE])"))
mutant("gnss_ekf-02", EKF_, "position covariance output as sigmas",
       ("cov[e] = np.diag(res.P_diag[last[e], L.DX_DP_SLICE])", "cov[e] = np.diag(np.sqrt(res.P_diag[last[e], L.DX_DP_SLICE]))"))
mutant("gnss_ekf-03", EKF_, "only the last clock jump kept", ("jump += k * MS_M", "jump = k * MS_M"))
mutant("gnss_ekf-04", EKF_, "clock jumps added to the pseudoranges",
       ("rows.pseudorange_m[idx] - jumps[spp.epoch_index[idx]],\n                                     filter_sigma_m",
        "rows.pseudorange_m[idx] + jumps[spp.epoch_index[idx]],\n                                     filter_sigma_m"))
mutant("gnss_ekf-05", EKF_, "start clock drift with the wrong sign",
       ("x0[L.X_C_DDT] = (clock[e1] - clock[e0])", "x0[L.X_C_DDT] = (clock[e0] - clock[e1])"))
mutant("gnss_ekf-06", EKF_, "start clock not corrected for jumps", ("clock = spp.clock_m - clock_jumps_m(spp)", "clock = spp.clock_m"))
mutant("gnss_ekf-07", EKF_, "records before the first solved epoch kept",
       ('    recs, ep = recs[recs["t"] >= first_t], ep[recs["t"] >= first_t]\n', ""))
mutant("gnss_ekf-08", EKF_, "range-rate variance given as sigma",
       ("rows.range_rate_mps[rr], K.RANGE_RATE_SIGMA_MPS**2,", "rows.range_rate_mps[rr], K.RANGE_RATE_SIGMA_MPS,"))
mutant("gnss_ekf-09", EKF_, "applied and gated counts swapped",
       ("np.add.at(ns, ep[is_pr & (res.status == STATUS_APPLIED)], 1)\n    np.add.at(gated, ep[is_pr & (res.status == STATUS_GATED)], 1)",
        "np.add.at(ns, ep[is_pr & (res.status == STATUS_GATED)], 1)\n    np.add.at(gated, ep[is_pr & (res.status == STATUS_APPLIED)], 1)"))
mutant("gnss_ekf-10", EKF_, "RAIM-excluded rows not given to the filter",
       ("np.isin(spp.row_status, (0, RAIM_EXCLUDED, EPOCH_UNSOLVED))", "np.isin(spp.row_status, (0, EPOCH_UNSOLVED))"))
mutant("gnss_ekf-11", CPL, "start fixes: a variance floor taken as the sigma",
       ("sig = np.sqrt(np.maximum(np.stack([cov[:, 0, 0], cov[:, 1, 1], cov[:, 2, 2]], axis=1), SPP_FIX_MIN_SIGMA_M**2))",
        "sig = np.maximum(np.stack([cov[:, 0, 0], cov[:, 1, 1], cov[:, 2, 2]], axis=1), SPP_FIX_MIN_SIGMA_M**2)"))
mutant("gnss_ekf-12", CPL, "start fixes: north sigma from the east variance",
       ("cov[:, 0, 0], cov[:, 1, 1], cov[:, 2, 2]", "cov[:, 0, 0], cov[:, 0, 0], cov[:, 2, 2]"))
mutant("gnss_ekf-13", CPL, "tightly coupled clock start not corrected for jumps",
       ("clock_m=spp.clock_m[ok] - jumps[ok]", "clock_m=spp.clock_m[ok]"))
mutant("gnss_ekf-14", CPL, "tightly coupled pseudoranges keep the clock jumps",
       ("pseudorange_m=rows.pseudorange_m[idx] - jumps[spp.epoch_index[idx]],", "pseudorange_m=rows.pseudorange_m[idx],"))

# ---------------------------------------------------------------- lnav/sfrbx
LNAV, SFR = "hardware/gnss/lnav.py", "leonav_runtime/gnss/sfrbx.py"
mutant("lnav-01", LNAV, "parity D25 with d22 in place of d23",
       ("(29, (1, 2, 3, 5, 6, 10, 11, 12, 13, 14, 17, 18, 20, 23)),", "(29, (1, 2, 3, 5, 6, 10, 11, 12, 13, 14, 17, 18, 20, 22)),"))
mutant("lnav-02", LNAV, "parity D29 with D29* in place of D30*",
       ("(30, (1, 3, 5, 6, 7, 9, 10, 14, 15, 16, 17, 18, 21, 22, 24)),", "(29, (1, 3, 5, 6, 7, 9, 10, 14, 15, 16, 17, 18, 21, 22, 24)),"))
mutant("lnav-03", LNAV, "D29* and D30* swapped in every parity bit",
       ("(d29_star if star == 29 else d30_star)", "(d30_star if star == 29 else d29_star)"))
mutant("lnav-04", LNAV, "subframe id read one bit early", ('Field("subframe_id", ((50, 3),))', 'Field("subframe_id", ((49, 3),))'))
mutant("lnav-05", LNAV, "af2 scale 2^-53", ('Field("af2", ((241, 8),), True, 2.0**-55)', 'Field("af2", ((241, 8),), True, 2.0**-53)'))
mutant("lnav-06", LNAV, "eccentricity scale 2^-32", ('Field("e", ((167, 8), (181, 24)), False, 2.0**-33)',
                                                    'Field("e", ((167, 8), (181, 24)), False, 2.0**-32)'))
mutant("lnav-07", LNAV, "IDOT unsigned", ('Field("idot", ((279, 14),), True, 2.0**-43, True)', 'Field("idot", ((279, 14),), False, 2.0**-43, True)'))
mutant("lnav-08", LNAV, "OMEGA DOT not in semicircles",
       ('Field("omega_dot", ((241, 24),), True, 2.0**-43, True)', 'Field("omega_dot", ((241, 24),), True, 2.0**-43)'))
mutant("lnav-09", LNAV, "HOW count taken as the subframe's own start", ("return self.tow_count * 6.0 - 6.0", "return self.tow_count * 6.0"))
mutant("lnav-10", SFR, "SV accuracy as the class upper bound", ('row["accuracy_m"] = lnav.URA_NOMINAL_M[s1.raw["ura"]]',
                                                               'row["accuracy_m"] = lnav.URA_UPPER_M[min(s1.raw["ura"], 14)]'))
mutant("lnav-11", SFR, "fit interval flag read the wrong way round",
       ('GPS_L1CA_FIT_FLAG1_S if s2.raw["fit_flag"] else', 'GPS_L1CA_FIT_FLAG1_S if not s2.raw["fit_flag"] else'))
mutant("lnav-12", SFR, "IODC compared with IODE on all 10 bits", ('iodc8 = s1.raw["iodc"] & 0xFF', 'iodc8 = s1.raw["iodc"]'))
mutant("lnav-13", SFR, "L2C/L5 SFRBX (sigId != 0) decoded as L1 C/A",
       ("if frame.gnss_id != 0 or frame.sig_id != 0 or len(frame.words) != 10:", "if frame.gnss_id != 0 or len(frame.words) != 10:"))
mutant("lnav-14", SFR, "toc taken from subframe 1 as seconds, not x16",
       ('row["toc"] = float(gtime.nearest_week_time(s1.value("toc"), t_tx))',
        'row["toc"] = float(gtime.nearest_week_time(s1.raw["toc"], t_tx))'))

# ---------------------------------------------------------------- eop
EOP = "leonav_runtime/orbits/eop.py"
mutant("eop-01", EOP, "the day index taken left of a row (midnight belongs to the day before)",
       ('np.searchsorted(self.mjd, mjd, side="right") - 1', 'np.searchsorted(self.mjd, mjd, side="left") - 1'))
mutant("eop-02", EOP, "leap seconds interpolated like the smooth part", ("+ leaps[day]", "+ np.interp(mjd, self.mjd, leaps)"))
mutant("eop-03", EOP, "x_p and y_p columns swapped",
       ("float(line[18:27]), float(line[37:46])", "float(line[37:46]), float(line[18:27])"))
mutant("eop-04", EOP, "measured flag read as prediction flag", ('line[57] == "I"', 'line[57] == "P"'))
mutant("eop-05", EOP, "polar motion read as milliarcseconds", ("ARCSEC_RAD = math.pi / (180.0 * 3600.0)",
                                                              "ARCSEC_RAD = math.pi / (180.0 * 3600.0 * 1000.0)"))
mutant("eop-06", EOP, "MJD of the Unix epoch off by half a day (JD confusion)", ("MJD_UNIX_EPOCH = 40587.0", "MJD_UNIX_EPOCH = 40587.5"))
mutant("eop-07", EOP, "requests before the table start not warned", ("if lo < self.mjd[0] or hi > self.mjd[-1]:", "if hi > self.mjd[-1]:"))
mutant("eop-08", EOP, "duplicated MJD rows accepted", ("np.any(np.diff(a[order, 0]) <= 0)", "np.any(np.diff(a[order, 0]) < 0)"))
mutant("eop-09", EOP, "stale predictions measured from the table end", ("elif hi - self.last_measured_mjd > PREDICTION_STALE_DAYS:",
                                                                      "elif hi - self.mjd[-1] > PREDICTION_STALE_DAYS:"))
mutant("eop-10", EOP, "a leap second unwrapped only when UT1-UTC rises by exactly 1 s",
       ("steps = np.round(np.diff(self.ut1_utc_s))", "steps = np.where(np.diff(self.ut1_utc_s) == 1.0, 1.0, 0.0)"))
