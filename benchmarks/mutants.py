"""Catalogue of realistic mutants for benchmarks/mutation.py.

One entry per bug a person could plausibly write: a flipped sign, swapped fields, a wrong
scale factor, an off-by-one bit or column, a dropped validity check, a changed default.
`edits` are (exact text, replacement) pairs; each text must occur exactly once in the file.
`equivalent` is set (with the reason) for a mutant that changes no behaviour a user could
see; such mutants are run but not scored.

MODULES maps a module name to its test files (fast, targeted ones first, so that pytest -x
stops early on a kill).
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Mutant:
    id: str
    module: str
    path: str
    what: str
    edits: tuple[tuple[str, str], ...]
    equivalent: str = ""


MODULES = {
    "gnss": {"files": ["hardware/gnss/nmea.py", "hardware/gnss/ubx.py"],
             "tests": ["tests/test_ubx_fields.py", "tests/test_nmea_fields.py", "tests/test_hardware_gnss.py"]},
    "tle": {"files": ["leonav_runtime/orbits/tle.py"],
            "tests": ["tests/test_tle_fields.py", "tests/test_orbits_elements.py"]},
    "beacons": {"files": ["leonav_runtime/beacons/associate.py", "leonav_runtime/beacons/lo_fit.py"],
                "tests": ["tests/test_beacons_lo_drift.py", "tests/test_beacons_joint.py",
                          "tests/test_beacons_association.py"]},
    "scenario": {"files": ["leonav_runtime/scenarios/load.py"], "tests": ["tests/test_scenario.py"]},
    "simulate": {"files": ["leonav_runtime/simulation/simulate.py", "leonav_runtime/simulation/satellites.py",
                           "leonav_runtime/simulation/visibility.py", "leonav_runtime/simulation/trial_block.py",
                           "leonav_runtime/simulation/sensor_errors.py"],
                 "tests": ["tests/test_simulate.py"]},
    "filter": {"files": ["leonav_runtime/core/filter.py"],
               "tests": ["tests/test_filter_api.py", "tests/test_runtime_filter.py"]},
    "models": {"files": ["models/"],
               "tests": ["tests/test_filter_api.py", "tests/test_models_physics.py", "tests/test_models_frames.py",
                         "tests/test_models_jacobians.py", "tests/test_models_doppler_rate_sgp4.py",
                         "tests/test_models_pcrb.py", "tests/test_runtime_filter.py", "tests/test_simulate.py"]},
}

_M: list[Mutant] = []


def mutant(id_, path, what, *edits, equivalent=""):
    module = next(k for k, v in MODULES.items() if any(path.startswith(f) for f in v["files"]))
    _M.append(Mutant(id_, module, path, what, tuple(edits), equivalent))


# ---------------------------------------------------------------- gnss: ubx.py, nmea.py
UBX, NMEA = "hardware/gnss/ubx.py", "hardware/gnss/nmea.py"
mutant("gnss-01", UBX, "NAV-PVT velocity north/east swapped",
       ("vel_ned_mps=(vel_n * 1e-3, vel_e * 1e-3,", "vel_ned_mps=(vel_e * 1e-3, vel_n * 1e-3,"))
mutant("gnss-02", UBX, "NAV-PVT headMot scaled 1e-7 instead of 1e-5",
       ("head_mot_rad=head_mot * 1e-5", "head_mot_rad=head_mot * 1e-7"))
mutant("gnss-03", UBX, "NAV-PVT pDOP scaled 0.1 instead of 0.01", ("pdop=pdop * 0.01", "pdop=pdop * 0.1"))
mutant("gnss-04", UBX, "NAV-TIMEGPS fTOW read as microseconds", ("ftow * 1e-9", "ftow * 1e-6"))
mutant("gnss-05", UBX, "NAV-PVT leap second (sec = 60) makes UTC None",
       ("hour, minute, min(sec, 59), tzinfo", "hour, minute, sec, tzinfo"))
mutant("gnss-06", UBX, "NAV-PVT carrSoln bits off by one", ("carr_soln=(flags >> 6) & 3", "carr_soln=(flags >> 5) & 3"))
mutant("gnss-07", UBX, "NAV-PVT nano subtracted", ("+ nano * 1e-9)", "- nano * 1e-9)"))
mutant("gnss-08", UBX, "NAV-PVT validDate/validTime bits swapped",
       ("valid_date, valid_time = bool(valid & 1), bool(valid & 2)",
        "valid_date, valid_time = bool(valid & 2), bool(valid & 1)"))
mutant("gnss-09", UBX, "NAV-PVT fullyResolved read from the validMag bit",
       ("fully_resolved=bool(valid & 4)", "fully_resolved=bool(valid & 8)"))
mutant("gnss-10", UBX, "NAV-PVT sAcc scaled as cm/s", ("s_acc_mps=s_acc * 1e-3", "s_acc_mps=s_acc * 1e-2"))
mutant("gnss-11", UBX, "NAV-PVT headAcc scaled 1e-2", ("head_acc_rad=head_acc * 1e-5", "head_acc_rad=head_acc * 1e-2"))
mutant("gnss-12", UBX, "NAV-PVT tAcc read as microseconds", ("t_acc_s=t_acc * 1e-9", "t_acc_s=t_acc * 1e-6"))
mutant("gnss-13", UBX, "NAV-PVT invalidLlh from the wrong flags3 bit", ("invalid_llh=bool(flags3 & 1)", "invalid_llh=bool(flags3 & 2)"))
mutant("gnss-14", UBX, "NAV-PVT gnssFixOK from the diffSoln bit", ("gnss_fix_ok=bool(flags & 1)", "gnss_fix_ok=bool(flags & 2)"))
mutant("gnss-15", UBX, "NAV-TIMEGPS leapSValid read from the weekValid bit",
       ("bool(valid & 2), bool(valid & 4), t_acc * 1e-9)", "bool(valid & 2), bool(valid & 2), t_acc * 1e-9)"))
mutant("gnss-16", UBX, "NAV-TIMEGPS tAcc in microseconds", ("bool(valid & 4), t_acc * 1e-9)", "bool(valid & 4), t_acc * 1e-6)"))
mutant("gnss-17", UBX, "RXM-RAWX cpStdev scaled 0.04", ("cp_std_cyc=0.004 *", "cp_std_cyc=0.04 *"))
mutant("gnss-18", UBX, "RXM-RAWX doStdev base 0.02", ("do_std_hz=0.002 *", "do_std_hz=0.02 *"))
mutant("gnss-19", UBX, "RXM-RAWX halfCyc from the subHalfCyc bit", ("half_cyc=bool(trk & 4)", "half_cyc=bool(trk & 8)"))
mutant("gnss-20", UBX, "RXM-RAWX clkReset from bit 2", ("bool(rec_stat & 2)", "bool(rec_stat & 4)"))
mutant("gnss-21", UBX, "RXM-RAWX prStdev without the 4-bit mask", ("0.01 * 2 ** (pr_sd & 0x0F)", "0.01 * 2 ** pr_sd"),
       equivalent="bits 4-7 of prStdev are reserved in the u-blox interface description and zero in all 17,873 "
                  "measurements of the three real RAWX logs; a masked and an unmasked read agree")
mutant("gnss-22", UBX, "RXM-MEASX codePhase scaled 2^-20", ("code_phase * 2.0 ** -21", "code_phase * 2.0 ** -20"))
mutant("gnss-23", UBX, "RXM-MEASX gpsTOWacc without the 2^-4 scale", ("gps_acc * 2.0 ** -4 * 1e-3", "gps_acc * 1e-3"))
mutant("gnss-24", UBX, "RXM-MEASX towSet mask 1 bit", ("flags & 3, sats)", "flags & 1, sats)"))
mutant("gnss-25", UBX, "UBX checksum CK_B sums bytes", ("ck_b = (ck_b + ck_a) & 0xFF", "ck_b = (ck_b + byte) & 0xFF"))
mutant("gnss-26", UBX, "gps_to_utc adds the leap seconds", ("+ tow_s - leap_s)", "+ tow_s + leap_s)"))
mutant("gnss-27", UBX, "NAV-PVT height and hMSL swapped", ("lon, lat, height, hmsl, h_acc", "lon, lat, hmsl, height, h_acc"))
mutant("gnss-28", NMEA, "NMEA checksum is a sum instead of XOR", ("value ^= byte", "value = (value + byte) & 0xFF"))
mutant("gnss-29", NMEA, "'*hh' length check dropped", ("if star < 0 or len(text) - star != 3:", "if star < 0:"))
mutant("gnss-30", NMEA, "'*hh' hex check dropped",
       ("        int(text[star + 1:], 16)\n    except ValueError:", "        pass\n    except ValueError:"))
mutant("gnss-31", NMEA, "pynmea2 no longer verifies the checksum", ("pynmea2.parse(decoded, check=True)", "pynmea2.parse(decoded, check=False)"),
       equivalent="pynmea2 verifies a checksum that is present whatever `check` says (check=True only makes a missing one an "
                  "error), and parse_sentence passes it only sentences ending in '*' and two hex digits; a wrong "
                  "checksum is still rejected (tests/test_nmea_fields.py)")
mutant("gnss-32", NMEA, "GGA ellipsoidal height = hMSL - separation", ("height_m=(hmsl + sep)", "height_m=(hmsl - sep)"))
mutant("gnss-33", NMEA, "GGA after midnight gets the previous day", ("date = date + _dt.timedelta(days=1)", "date = date"))
mutant("gnss-34", NMEA, "ZDA day and month swapped",
       ("_dt.date(int(msg.year), int(msg.month), int(msg.day))", "_dt.date(int(msg.year), int(msg.day), int(msg.month))"))
mutant("gnss-35", NMEA, "west longitude not negated", ('if hemisphere in ("S", "W")', 'if hemisphere in ("S",)'))
mutant("gnss-36", NMEA, "'quality == 0' check dropped (a GGA without a fix gives one)",
       ("        if quality == 0:\n            return None\n        lat = ", "        lat = "))
mutant("gnss-37", NMEA, "GGA hdop field not read", ("hdop=_to_float(msg.horizontal_dil)", "hdop=None"))
mutant("gnss-38", NMEA, "GGA number of satellites ignored", ("num_sv = int(msg.num_sats or 0)", "num_sv = 0"))

# ---------------------------------------------------------------- tle.py
TLE = "leonav_runtime/orbits/tle.py"
mutant("tle-01", TLE, "Alpha-5 decoded off by 10,000",
       ("return (10 + _ALPHA5_LETTERS.index(letter)) * 10000", "return (9 + _ALPHA5_LETTERS.index(letter)) * 10000"))
mutant("tle-02", TLE, "Alpha-5 letters I and O not rejected",
       ('_ALPHA5_LETTERS = "ABCDEFGHJKLMNPQRSTUVWXYZ"', '_ALPHA5_LETTERS = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"'))
mutant("tle-03", TLE, "a blank float field read as 0", ("if not text and blank_is_zero:", "if not text:"))
mutant("tle-04", TLE, "integer-field validation dropped",
       ("    if not text.isdigit():\n        raise TLEFieldError(f\"non-numeric field {name} (columns {first}-{last}): {text!r}\")\n    return int(text)",
        "    return int(text)"))
mutant("tle-05", TLE, "Alpha-5 encoded off by 10,000", ("_ALPHA5_LETTERS[norad_id // 10000 - 10]", "_ALPHA5_LETTERS[norad_id // 10000 - 9]"))
mutant("tle-06", TLE, "Alpha-5 length check dropped", ("or not text[1:].isdigit() or len(text) != 5:", "or not text[1:].isdigit():"))
mutant("tle-07", TLE, "checksum ignores minus signs", ('_CHECKSUM_WEIGHTS[ord("-")] = 1\n', ""))
mutant("tle-08", TLE, "epoch year 57 read as 2057", ("year += 1900 if year >= 57 else 2000", "year += 1900 if year > 57 else 2000"))
mutant("tle-09", TLE, "implied-exponent sign dropped", ('return -value if sign == "-" else value', "return value"))
mutant("tle-10", TLE, "implied exponent with the wrong sign", ('(10.0 ** int(exponent or "+0"))', '(10.0 ** -int(exponent or "+0"))'))
mutant("tle-11", TLE, "eccentricity scaled 1e-6", ("return int(text) * 1e-7", "return int(text) * 1e-6"))
mutant("tle-12", TLE, "inclination columns off by one", ('_float(line2, 9, 16, "inclination")', '_float(line2, 10, 17, "inclination")'))
mutant("tle-13", TLE, "catalogue numbers of the two lines not compared", ("if norad1 != norad2:", "if False:"))
mutant("tle-14", TLE, "zero mean motion accepted", ("if fields.mean_motion_revday <= 0.0:", "if fields.mean_motion_revday < 0.0:"))
mutant("tle-15", TLE, "inclination of exactly 180 deg rejected",
       ("if not 0.0 <= fields.inclination_deg <= 180.0:", "if not 0.0 <= fields.inclination_deg < 180.0:"))
mutant("tle-16", TLE, "epoch day 0 accepted", ("if not 1.0 <= day < 367.0:", "if not 0.0 <= day < 367.0:"))
mutant("tle-17", TLE, "text glued after column 69 accepted",
       ("if len(line) > TLE_LINE_LENGTH and not line[TLE_LINE_LENGTH].isspace():", "if False:"))
mutant("tle-18", TLE, "checksum verified against column 68", ("computed != int(line[-1])", "computed != int(line[-2])"))
mutant("tle-19", TLE, "epoch day not counted from 1", ("return start + _dt.timedelta(days=day - 1.0)", "return start + _dt.timedelta(days=day)"))
mutant("tle-20", TLE, "writer: mantissa rounding carry lost", ("if digits >= 100000:", "if digits > 100000:"))
mutant("tle-21", TLE, "writer: negative first derivative loses its sign", ('return ("-" if value < 0 else " ") + text', 'return " " + text'))
mutant("tle-22", TLE, "wrong line number not rejected", ("if line[0] != str(expected_number):", "if False:"))
mutant("tle-23", TLE, "mean-motion columns shifted", ('_float(line2, 53, 63, "mean motion")', '_float(line2, 52, 63, "mean motion")'),
       equivalent="column 52 is the blank separator before the mean motion; a blank is stripped, so the value is the same")

# ---------------------------------------------------------------- beacons: associate.py, lo_fit.py
ASC, LOF = "leonav_runtime/beacons/associate.py", "leonav_runtime/beacons/lo_fit.py"
mutant("beacons-01", ASC, "comb cost: LO drift added to the Doppler instead of removed",
       ("r = m.doppler_hz[None, :] - D - drift * m.t_s[None, :]", "r = m.doppler_hz[None, :] - D + drift * m.t_s[None, :]"))
mutant("beacons-02", ASC, "comb cost: LO drift added to the rate instead of removed",
       ("r_a = m.rate_hz_s[None, :] - A - drift\n", "r_a = m.rate_hz_s[None, :] - A + drift\n"))
mutant("beacons-03", ASC, "leave-one-out offset ignores the drift",
       ("np.asarray([r.intercept(drift) for r in res])", "np.asarray([r.intercept(0.0) for r in res])"))
mutant("beacons-04", ASC, "ambiguous combs feed the capture's LO estimate",
       ('good = [i for i in status if status[i][0] == "associated"]', 'good = [i for i in status if status[i][0] != "unassociated"]'))
mutant("beacons-05", ASC, "default max_cost 5 -> 10", ("max_cost: float = 5.0", "max_cost: float = 10.0"))
mutant("beacons-06", ASC, "default ambiguity_ratio 1.5 -> 1.2", ("ambiguity_ratio: float = 1.5", "ambiguity_ratio: float = 1.2"))
mutant("beacons-07", ASC, "default min_epochs 2 -> 1", ("min_epochs: int = 2", "min_epochs: int = 1"))
mutant("beacons-08", ASC, "ambiguity ratio without the floor at 1", ("ratio = c2 / max(k.cost[j], 1.0)", "ratio = c2 / k.cost[j]"))
mutant("beacons-09", ASC, "leave-one-out dropped (a comb confirms itself)",
       ("_common([r for o, r in resid.items() if o != i], spacing)", "_common(list(resid.values()), spacing)"))
mutant("beacons-10", ASC, "filter rate: drift added instead of removed", ("rate = rate - lo.drift_hz_s", "rate = rate + lo.drift_hz_s"))
mutant("beacons-11", ASC, "filter rate sigma without the drift's", ("sig = np.hypot(sig, lo.sigma_drift_hz_s)", "sig = sig"))
mutant("beacons-12", ASC, "filter Doppler: tone shift added", ("doppler_hz=m.doppler_hz - tone_shift_hz", "doppler_hz=m.doppler_hz + tone_shift_hz"))
mutant("beacons-13", ASC, "drift removed from a single comb",
       ("elif slopes.shape[0] < cfg.min_combs_for_drift:", "elif slopes.shape[0] < 1:"))
mutant("beacons-14", ASC, "drift removed even when the combs' slopes disagree",
       ("elif spread > cfg.max_drift_spread_hz_s:", "elif False:"))
mutant("beacons-15", ASC, "too-short combs not rejected", ("if n_ep < cfg.min_epochs else", "if n_ep < 1 else"))
mutant("beacons-16", ASC, "reported residual ignores the removed drift", ("r_a = m.rate_hz_s - A - drift_out", "r_a = m.rate_hz_s - A"))
mutant("beacons-17", LOF, "wrap to [0, period) instead of centred", ("np.floor(np.asarray(x) / period + 0.5)", "np.floor(np.asarray(x) / period)"))
mutant("beacons-18", LOF, "robust mean keeps outliers (30 sigma)", ("inl = np.abs(v - m) <= 3 * s\n    if inl.any():", "inl = np.abs(v - m) <= 30 * s\n    if inl.any():"))
mutant("beacons-19", LOF, "circular offset score not capped", ("score = float(np.sum(np.minimum(u**2, 9.0)))", "score = float(np.sum(u**2))"))
mutant("beacons-20", LOF, "drift estimate picks the less precise of slope and rate mean", ("if sig_rate < sig_fit:", "if sig_rate > sig_fit:"))
mutant("beacons-21", LOF, "intercept adds the drift", ("return self.mean_resid_hz - drift_hz_s * self.mean_t_s", "return self.mean_resid_hz + drift_hz_s * self.mean_t_s"))
mutant("beacons-22", LOF, "drift sigma ignores the prediction's jerk", ("np.sqrt(sig_fit**2 + (jerk * time_sigma_s) ** 2 + drift_floor_hz_s**2)", "np.sqrt(sig_fit**2 + drift_floor_hz_s**2)"))
mutant("beacons-23", LOF, "robust mean sigma not inflated by the scatter", ("sig *= max(1.0, np.sqrt(chi2))", "sig *= 1.0"))

# ---------------------------------------------------------------- scenario.py
SCN = "leonav_runtime/scenarios/load.py"
mutant("scenario-01", SCN, "NaN/inf accepted", ("if isinstance(given, float) and not _finite(given):", "if False:"))
mutant("scenario-02", SCN, "booleans accepted as numbers",
       ("if not isinstance(value, kinds) or (isinstance(value, bool) and bool not in kinds):", "if not isinstance(value, kinds):"))
mutant("scenario-03", SCN, "lower bound made exclusive", ("(spec.lo is not None and value < spec.lo)", "(spec.lo is not None and value <= spec.lo)"))
mutant("scenario-04", SCN, "upper bound made exclusive", ("(spec.hi is not None and value > spec.hi)", "(spec.hi is not None and value >= spec.hi)"))
mutant("scenario-05", SCN, "integers no longer accepted for float fields",
       ("if float in kinds and isinstance(value, int) and not isinstance(value, bool):", "if False:"))
mutant("scenario-06", SCN, "inf accepted in number lists (NaN still fails the limit test)",
       ("and not isinstance(v, bool) and _finite(v) and abs(v) <= limit for v in value", "and not isinstance(v, bool) and abs(v) <= limit for v in value"))
mutant("scenario-07", SCN, "booleans accepted in number lists", ("isinstance(v, (int, float)) and not isinstance(v, bool) and _finite(v)", "isinstance(v, (int, float)) and _finite(v)"))
mutant("scenario-08", SCN, "outage may end after the run", ("if not 0 <= a < b <= duration:", "if not 0 <= a < b:"))
mutant("scenario-09", SCN, "zero-length manoeuvre accepted", ('(("duration", row[0], 1e-3, 86400, "s"),', '(("duration", row[0], 0, 86400, "s"),'))
mutant("scenario-10", SCN, "choices not checked", ("if spec.choices is not None and value not in spec.choices:", "if False:"))
mutant("scenario-11", SCN, "unknown keys accepted", ("            unknown = set(given) - set(fields)\n", "            unknown = set()\n"))
mutant("scenario-12", SCN, "roll amplitude left in degrees", ('traj["roll_amplitude_rad"] = math.radians(traj.pop("roll_amplitude_deg"))', 'traj["roll_amplitude_rad"] = traj.pop("roll_amplitude_deg")'))
mutant("scenario-13", SCN, "element files not relative to the scenario file",
       ("element_files = [(base / f) if not Path(f).is_absolute() else Path(f) for f in files]", "element_files = [Path(f) for f in files]"))
mutant("scenario-14", SCN, "counts neither sorted nor de-duplicated", ('star["counts"] = sorted(set(counts))', 'star["counts"] = list(counts)'))
mutant("scenario-15", SCN, "modes reordered", ("modes = list(dict.fromkeys(modes))", "modes = sorted(set(modes))"))
mutant("scenario-16", SCN, "booleans accepted as Starlink counts", ("all(isinstance(c, int) and not isinstance(c, bool) and 1 <= c", "all(isinstance(c, int) and 1 <= c"))
mutant("scenario-17", SCN, "files source with no files accepted", ('if values["elements"]["source"] == "files" and not element_files:', "if False:"))
mutant("scenario-18", SCN, "attitude sigma left in degrees", ('filt["initial_attitude_sigma_rad"] = math.radians(filt.pop("initial_attitude_sigma_deg"))', 'filt["initial_attitude_sigma_rad"] = filt.pop("initial_attitude_sigma_deg")'))

# ---------------------------------------------------------------- simulate.py
SIM = "leonav_runtime/simulation/simulate.py"
SAT, VIS = "leonav_runtime/simulation/satellites.py", "leonav_runtime/simulation/visibility.py"
BLK, ERR = "leonav_runtime/simulation/trial_block.py", "leonav_runtime/simulation/sensor_errors.py"
mutant("simulate-01", SAT, "light-time correction deleted",
       ("r_tx, v_tx, _ = nav.transmit_state(states.r_ecef_m[s, j], states.v_ecef_mps[s, j], a, r_rx[j])",
        "r_tx, v_tx = states.r_ecef_m[s, j], states.v_ecef_mps[s, j]"))
mutant("simulate-02", SAT, "light-time correction with the wrong sign (satellite moved forward by v tau)",
       ("            rows.append((k, t[j], int(es.norad_ids[s]), np.concatenate([r_tx, v_tx, a]), None, rank))",
        "            r_tx = 2 * states.r_ecef_m[s, j] - r_tx\n"
        "            rows.append((k, t[j], int(es.norad_ids[s]), np.concatenate([r_tx, v_tx, a]), None, rank))"))
mutant("simulate-03", SAT, "GPS velocity taken at receive time", ("np.concatenate([r_tx, v_tx, a])", "np.concatenate([r_tx, states.v_ecef_mps[s, j], a])"))
mutant("simulate-04", SAT, "GPS visibility checked at the best epoch",
       ("None, rank))\n    vis = [len(r) for r in ranked]\n    return rows, min(vis) if vis else 0",
        "None, rank))\n    vis = [len(r) for r in ranked]\n    return rows, max(vis) if vis else 0"))
mutant("simulate-05", SAT, "Starlink visibility checked at the best epoch",
       ("for rank, s in enumerate(use)]\n    vis = [len(r) for r in ranked]\n    return rows, min(vis) if vis else 0",
        "for rank, s in enumerate(use)]\n    vis = [len(r) for r in ranked]\n    return rows, max(vis) if vis else 0"))
mutant("simulate-06", SAT, "max_satellites ignored for GPS", ('use = ranked[j][: scn.gps["max_satellites"]]', "use = ranked[j]"))
mutant("simulate-07", SAT, "measurement rate that does not divide the IMU rate accepted",
       ("if step < 1 or abs(scn.imu_rate_hz / rate_hz - step) > 1e-9:", "if step < 1:"))
mutant("simulate-08", SAT, "Starlink reference is the lowest satellite", ("sat[rank], sat[0], rank)", "sat[rank], sat[-1], rank)"))
mutant("simulate-09", VIS, "satellites ranked lowest first", ('ranked.append(vis[np.argsort(-key, kind="stable")])', 'ranked.append(vis[np.argsort(key, kind="stable")])'))
mutant("simulate-10", SAT, "GPS uses the Starlink elevation mask",
       ('_visible_ranked(scn, es, t, p_enu, scn.gps["elevation_mask_rad"], notes)',
        '_visible_ranked(scn, es, t, p_enu, scn.starlink["elevation_mask_rad"], notes)'))
mutant("simulate-11", SAT, "first measurement epoch at t = 0", ("return np.arange(step, t_imu.size, step)", "return np.arange(0, t_imu.size, step)"))
mutant("simulate-12", SIM, "clock and LO enter with the wrong sign", ("z += s.H[rows, b.error_offset + j] * value", "z -= s.H[rows, b.error_offset + j] * value"))
mutant("simulate-13", SIM, "noise added to noise-free trials", ("z += g * sigma * noise[:, rows]", "z += sigma * noise[:, rows]"))
mutant("simulate-14", BLK, "Doppler-rate aux f_b of one IMU sample while R assumes the 0.1 s average (block builder)",
       ("n_avg = max(1, int(round(F_B_AVERAGE_S / float(np.median(imu.dt)))))", "n_avg = 1"))
mutant("simulate-15", SIM, "GPS outages keep only the outage", ("keep &= ~((s.t_s >= a) & ((s.t_s < b) | (b >= end_s)))", "keep &= ((s.t_s >= a) & ((s.t_s < b) | (b >= end_s)))"))
mutant("simulate-16", BLK, "aux keeps the true instead of the measured specific force (block builder)",
       ("        flat[f_b_at] = np.take(self.f_b[j], tpl.fb_sample, axis=0)\n", ""))
mutant("simulate-17", SIM, "count selects one satellite too many", ("return np.flatnonzero(s.rank < count)", "return np.flatnonzero(s.rank <= count)"))
mutant("simulate-18", SAT, "OFDM difference includes the reference itself", ("return [r for r in rows if r[5] > 0]", "return [r for r in rows if r[5] >= 0]"))
mutant("simulate-19", ERR, "clock and LO truth start from the scenario values with the wrong sign",
       ("    value = float(getattr(scn, section)[key])", "    value = -float(getattr(scn, section)[key])"))
mutant("simulate-20", SIM, "too few GPS satellites accepted", ('if "gps" in needed and visible["gps"] < 4:', 'if "gps" in needed and visible["gps"] < 1:'))

# ---------------------------------------------------------------- filter.py
FIL = "leonav_runtime/core/filter.py"
mutant("filter-01", FIL, "gate mapping ignored", ("vec[self.lib.kind_id(kind)] = float(value)", "pass"))
mutant("filter-02", FIL, "gate None means the default gate", ("if gate is None:\n            return np.zeros(n)", "if gate is None:\n            return np.full(n, CHI2_1DOF_999)"))
mutant("filter-03", FIL, "update reports applied when gated", ("return self.status == STATUS_APPLIED", "return self.status != STATUS_FAILED"))
mutant("filter-04", FIL, "P_rows accepts repeated indices", ("np.any(np.diff(rows) <= 0)", "np.any(np.diff(rows) < 0)"))
mutant("filter-05", FIL, "P_rows accepts an index past the end", ("rows[-1] >= n)", "rows[-1] > n)"))
mutant("filter-06", FIL, "h() ignores the given state", ("x_v = self.x if x is None else self._vector(\"x\", x, self.nx)", "x_v = self.x"))
mutant("filter-07", FIL, "run() ignores a per-call gate", ('gates = self.gate if isinstance(gate, str) and gate == "filter" else self.gate_vector(gate)', "gates = self.gate"))
mutant("filter-08", FIL, "P0 shape not checked", ("        if arr.shape != (self.ndx, self.ndx):\n            raise ValueError", "        if False:\n            raise ValueError"))
mutant("filter-09", FIL, "vector length not checked", ("        if arr.size != n:\n            raise ValueError", "        if False:\n            raise ValueError"))
mutant("filter-10", FIL, "default chi-square gate at 99 % (6.63)", ("gate: GateSpec = CHI2_1DOF_999,", "gate: GateSpec = 6.634896601021214,"))
mutant("filter-11", FIL, "full P blocks returned transposed", ("p_hist = p_hist.transpose(0, 2, 1)  # each block was written column-major", "pass"),
       equivalent="P is exactly symmetric (the generated predict and update form the upper triangle and mirror it; "
                  "every block of a run equals its transpose bit for bit), so the transpose changes nothing")
mutant("filter-12", FIL, "x_prior not saved after predict",
       ('returned {compiled.code_name(rc)}")\n        self.status = STATUS_IMU if rc == _codes.OK else STATUS_FAILED\n'
        '        self.x_prior, self.P_prior = self.x.copy(), self.P.copy(order="F")\n        return self.status\n\n    def predict_cv',
        'returned {compiled.code_name(rc)}")\n        self.status = STATUS_IMU if rc == _codes.OK else STATUS_FAILED\n'
        '        return self.status\n\n    def predict_cv'))
mutant("filter-13", FIL, "pcrb x_lin shape not checked", ("    if x_lin.shape != (n, nx):\n", "    if False:\n"))
mutant("filter-14", FIL, "update ignores aux", ("aux_v = np.zeros(records.NAUX) if aux is None else self._vector(\"aux\", aux, records.NAUX)\n        ysn",
                                                  "aux_v = np.zeros(records.NAUX)\n        ysn"))

# ---------------------------------------------------------------- models/ (C regenerated per mutant)
mutant("models-01", "models/measurements/gnss_pseudorange.py", "Sagnac term with the wrong sign",
       ("(r_S[0] * r_U[1] - r_S[1] * r_U[0])", "(r_S[1] * r_U[0] - r_S[0] * r_U[1])"))
mutant("models-02", "models/measurements/doppler_rate.py", "Doppler rate with the wrong sign",
       ("return -(p[P[\"f_c_hz\"].offset] / C_LIGHT_MPS) * rho_ddot", "return (p[P[\"f_c_hz\"].offset] / C_LIGHT_MPS) * rho_ddot"))
mutant("models-03", "models/measurements/geometry.py", "range acceleration: + (u.v)^2",
       ("(ca.dot(v_rel, v_rel) - rho_dot**2) / rho", "(ca.dot(v_rel, v_rel) + rho_dot**2) / rho"))
mutant("models-04", "models/kinematics.py", "receiver acceleration: Coriolis with the wrong sign",
       ("gravity_enu(x[X[\"p_enu\"].slice], p) - 2 * ca.cross(w_ie, v)", "gravity_enu(x[X[\"p_enu\"].slice], p) + 2 * ca.cross(w_ie, v)"))
mutant("models-05", "models/kinematics.py", "mechanization: Coriolis without the factor 2",
       ("return gravity(pos_, p) - 2 * ca.cross(w_ie, vel_)", "return gravity(pos_, p) - ca.cross(w_ie, vel_)"))
mutant("models-06", "models/kinematics.py", "Earth rate north/up components swapped",
       ("ca.vertcat(0, ca.cos(lat0), ca.sin(lat0))", "ca.vertcat(0, ca.sin(lat0), ca.cos(lat0))"))
mutant("models-07", "models/gravity.py", "Somigliana with the wrong sign of k", ("(1 + K.SOMIGLIANA_K * s2)", "(1 - K.SOMIGLIANA_K * s2)"))
mutant("models-08", "models/measurements/doppler.py", "Doppler: LO offset subtracted", ("* rho_dot + x[X[\"b_lo\"].offset]", "* rho_dot - x[X[\"b_lo\"].offset]"))
mutant("models-09", "models/clock.py", "clock bias noise dt^3/2", ("q_cddt * dt**3 / 3", "q_cddt * dt**3 / 2"))
mutant("models-10", "models/dynamics.py", "clock bias (an integral block) not integrated over dt",
       ("out.append(b + x[X[d.of].slice] * dt)", "out.append(b + x[X[d.of].slice])"))
mutant("models-11", "models/kinematics.py", "Earth rotation applied the wrong way", ("e_n, e_b = frames.quat_exp(-w_ie * dt / 2)", "e_n, e_b = frames.quat_exp(w_ie * dt / 2)"))
mutant("models-12", "models/ekf.py", "Joseph update: c = b - S K", ("c = b - S * K / 2", "c = b - S * K"))
mutant("models-13", "models/measurements/ofdm_range_difference.py", "OFDM difference reversed",
       ("return ca.norm_2(aux[AUX[\"r_S_ecef\"].slice] - r_U) - ca.norm_2(aux[AUX[\"r_ref_ecef\"].slice] - r_U)",
        "return ca.norm_2(aux[AUX[\"r_ref_ecef\"].slice] - r_U) - ca.norm_2(aux[AUX[\"r_S_ecef\"].slice] - r_U)"))
mutant("models-14", "models/dynamics.py", "LO random walk noise not scaled by dt",
       ("diag[blk] = q * dt\n", 'diag[blk] = q if s.name == "b_lo" else q * dt\n'))

# ---------------------------------------------------------------- second batch
# Written after the tests above, without looking at which of them would fail: a check on
# how far the tests generalise beyond the mutants they were written against.
mutant("gnss-39", UBX, "NAV-PVT lat and lon swapped", ("lon, lat, height, hmsl, h_acc, v_acc = struct", "lat, lon, height, hmsl, h_acc, v_acc = struct"))
mutant("gnss-40", UBX, "RXM-RAWX sigId and freqId swapped",
       ("(pr, cp, do, gnss_id, sv_id, sig_id, freq_id, lock_ms, cno,", "(pr, cp, do, gnss_id, sv_id, freq_id, sig_id, lock_ms, cno,"))
mutant("gnss-41", UBX, "RXM-RAWX payload length not checked", ("    if len(p) != 16 + 32 * num_meas:\n        raise", "    if False:\n        raise"))
mutant("gnss-42", UBX, "NAV-PVT short payload accepted", ("if len(p) < 84:", "if len(p) < 78:"))
mutant("gnss-43", UBX, "NAV-TIMEGPS long payload accepted", ("    if len(p) != 16:\n", "    if len(p) < 16:\n"))
mutant("gnss-44", UBX, "ACK-NAK reported as acknowledged", ("frame.msg_id == 0x01, frame.payload[0]", "frame.msg_id == 0x00, frame.payload[0]"))
mutant("gnss-45", UBX, "RXM-MEASX dopplerHz scaled 0.02", ("dop_hz * 0.2", "dop_hz * 0.02"))
mutant("gnss-46", NMEA, "rollover uses minutes for hours", ("self._date_tod_s = tod.hour * 3600 + tod.minute * 60", "self._date_tod_s = tod.hour * 60 + tod.minute * 60"))
mutant("gnss-47", NMEA, "south latitude not negated", ('if hemisphere in ("S", "W")', 'if hemisphere in ("W",)'))
mutant("tle-24", TLE, "classification read from column 7", ("classification=line1[7],", "classification=line1[6],"))
mutant("tle-25", TLE, "international designator loses its last column", ("intl_designator=_field(line1, 10, 17)", "intl_designator=_field(line1, 10, 16)"))
mutant("tle-26", TLE, "element-set number loses its thousands digit", ('_int(line1, 65, 68, "element-set number")', '_int(line1, 66, 68, "element-set number")'))
mutant("tle-27", TLE, "epoch day loses its last decimal", ('_float(line1, 21, 32, "epoch day")', '_float(line1, 21, 31, "epoch day")'))
mutant("tle-28", TLE, "writer: eccentricity not range-checked", ("if not 0 <= ecc_digits <= 9999999:", "if False:"))
mutant("beacons-24", ASC, "Doppler scale takes the smaller of floor and sigma",
       ("    s_f = max(cfg.doppler_floor_hz, float(np.median(m.sigma_doppler_hz)))\n    s_a = max(cfg.rate_floor_hz_s, float(np.median(m.sigma_rate_hz_s)))\n    terms",
        "    s_f = min(cfg.doppler_floor_hz, float(np.median(m.sigma_doppler_hz)))\n    s_a = max(cfg.rate_floor_hz_s, float(np.median(m.sigma_rate_hz_s)))\n    terms"))
mutant("beacons-25", ASC, "offset reported pinned when only bounded", ("pinned = lo == hi", "pinned = lo <= hi"))
mutant("beacons-26", LOF, "offset sigma without the floor", ("sig_off = float(np.hypot(offset_floor_hz, time_sigma_s", "sig_off = float(np.hypot(0.0, time_sigma_s"))
mutant("beacons-27", LOF, "circular offset sigma 1/sum(w)", ("return centre, float(1.0 / np.sqrt(np.sum(w))), inl", "return centre, float(1.0 / np.sum(w)), inl"))
mutant("beacons-28", LOF, "rate-mean sigma without the overlap factor", ("sig_rate = float(np.sqrt(2 * np.mean(sigma_rate_hz_s**2) / t_s.size))", "sig_rate = float(np.sqrt(np.mean(sigma_rate_hz_s**2) / t_s.size))"))
mutant("beacons-29", ASC, "joint_lo=False ignored", ("if not cfg.joint_lo or new == assign:", "if new == assign:"))
mutant("scenario-19", SCN, "a count of 1 rejected", ("and 1 <= c <= MAX_COUNT for c in counts)", "and 1 < c <= MAX_COUNT for c in counts)"))
mutant("scenario-20", SCN, "unknown top-level keys accepted", ('if key not in schema and key not in schema.get("", {}):', "if False:"))
mutant("scenario-21", SCN, "an outage may start at its end", ("if not 0 <= a < b <= duration:", "if not 0 <= a <= b <= duration:"))
mutant("scenario-22", SCN, "pitch amplitude left in degrees", ('traj["pitch_amplitude_rad"] = math.radians(traj.pop("pitch_amplitude_deg"))', 'traj["pitch_amplitude_rad"] = traj.pop("pitch_amplitude_deg")'))
mutant("simulate-21", SIM, "specific force of the next interval at each sample", ("f_b = np.vstack([dvel[:1], dvel]) / dt", "f_b = np.vstack([dvel, dvel[-1:]]) / dt"))
mutant("simulate-22", SAT, "light time without the satellite's acceleration (0.5 a tau^2 dropped)",
       ("nav.transmit_state(states.r_ecef_m[s, j], states.v_ecef_mps[s, j], a, r_rx[j])",
        "nav.transmit_state(states.r_ecef_m[s, j], states.v_ecef_mps[s, j], 0 * a, r_rx[j])"))
mutant("simulate-23", SIM, "outage end included", ("keep &= ~((s.t_s >= a) & ((s.t_s < b) | (b >= end_s)))", "keep &= ~((s.t_s >= a) & ((s.t_s <= b) | (b >= end_s)))"))
mutant("simulate-24", SIM, "position and velocity prior sigmas swapped",
       ('prior_sigmas(layout, profile, f["initial_position_sigma_m"], f["initial_velocity_sigma_mps"],',
        'prior_sigmas(layout, profile, f["initial_velocity_sigma_mps"], f["initial_position_sigma_m"],'))
mutant("simulate-25", SIM, "noise drawn only for the mode's observables",
       ("        noise = np.stack([(r if o.paper else own_stream(r, o.name)).standard_normal(s.t_s.size) for r in rngs])\n"
        "        if o not in parsed.observables:\n            continue\n",
        "        if o not in parsed.observables:\n            continue\n"
        "        noise = np.stack([(r if o.paper else own_stream(r, o.name)).standard_normal(s.t_s.size) for r in rngs])\n"))
# the block builder (issue 25): written with it, each a bug the per-trial road could not have
mutant("simulate-26", BLK, "averaging window of f_b one sample short", ("np.maximum(ends - n_avg, 0)", "np.maximum(ends - n_avg + 1, 0)"))
mutant("simulate-27", SIM, "prior drawn with the variances as sigmas", ("factor_t = (u * np.sqrt(s)).T", "factor_t = (u * s).T"))
mutant("simulate-28", SIM, "measuring sensors' truth one IMU sample early in z", ("value = errors[b.name][:, k, j]", "value = errors[b.name][:, k - 1, j]"))
mutant("simulate-29", ERR, "clock bias integrates the drift at the end of each step", ("x_d[:, :-1] * np.diag(Phi[e, d])", "x_d[:, 1:] * np.diag(Phi[e, d])"))
mutant("simulate-30", ERR, "IMU bias of the interval's end added to its increment", ("u_true[:, :3], b_g[:, :-1] * dt + w_g", "u_true[:, :3], b_g[:, 1:] * dt + w_g"))
mutant("simulate-31", BLK, "block measurements written in the template's record order", ("flat[z_at] = np.take(self.z[j], tpl.meas_src)", "flat[z_at] = np.take(self.z[j], np.sort(tpl.meas_src))"))
mutant("simulate-32", ERR, "every trial of a block draws the first trial's own-stream blocks",
       ('rs = list(rngs) if b.truth["stream"] == "trial" else [own_stream(r, b.name) for r in rngs]',
        'rs = list(rngs) if b.truth["stream"] == "trial" else [own_stream(rngs[0], b.name)] * len(rngs)'))
mutant("simulate-33", ERR, "every trial of a block starts its bias walks at the first trial's start",
       ("columnwise(np.add, x0[:, None], np.cumsum", "columnwise(np.add, x0[:1, None], np.cumsum"))
mutant("simulate-34", ERR, "a block's prior start drawn without its sigma (a unit normal)", ("            out *= factor\n", ""))
mutant("filter-15", FIL, "record stream not checked", ("        records.check_records(recs, len(self.lib.meas_ids))\n        n = recs.size\n        gates", "        n = recs.size\n        gates"))
mutant("filter-16", FIL, "applied and gated counts swapped", ("int(out.n_imu), int(out.n_applied), int(out.n_gated),", "int(out.n_imu), int(out.n_gated), int(out.n_applied),"))
mutant("filter-17", FIL, "a number as gate ignored", ("return np.full(n, float(gate))", "return np.full(n, CHI2_1DOF_999)"))
mutant("filter-18", FIL, "PCRB 9x9 blocks not transposed", ("return PcrbResult(recs[\"t\"].copy(), B_diag, B_nav.transpose(0, 2, 1), B)", "return PcrbResult(recs[\"t\"].copy(), B_diag, B_nav, B)"),
       equivalent="the PCRB blocks are exactly symmetric (every block of a run equals its transpose bit for bit), "
                  "so the transpose changes nothing")
mutant("models-15", "models/gravity.py", "height term with the wrong sign", ("return g0 * (1 - 2 / a *", "return g0 * (1 + 2 / a *"))
mutant("models-16", "models/ekf.py", "gyro noise uses the velocity random walk",
       ('ca.repmat(p[P["arw"].offset] ** 2 * dt, U["dtheta_b"].size, 1)', 'ca.repmat(p[P["vrw"].offset] ** 2 * dt, U["dtheta_b"].size, 1)'))
mutant("models-17", "models/measurements/gnss_fix.py", "north velocity reads the east component",
       ('    """North antenna velocity (m/s)."""\n    return antenna_velocity(x, aux, p)[1]',
        '    """North antenna velocity (m/s)."""\n    return antenna_velocity(x, aux, p)[0]'))
mutant("models-18", "models/ekf.py", "information update adds H H^T R", ("return J + ca.mtimes(H.T, H) / R", "return J + ca.mtimes(H.T, H) * R"))

# Further groups live in their own files (one per area, so they can grow independently); each
# adds its MODULES entries and calls mutant() on import.
import mutants_gnss  # noqa: E402,F401
import mutants_runtime  # noqa: E402,F401

MUTANTS: list[Mutant] = _M
_ids = [m.id for m in MUTANTS]
assert len(set(_ids)) == len(_ids), "duplicate mutant id"
