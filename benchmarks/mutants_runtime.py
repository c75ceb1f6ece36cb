"""Mutant catalogue, runtime: dataset/, nav/, live/, observability/, beacons/ (doppler, ridges, waterfall, pipeline).

Same rules as benchmarks/mutants.py: one realistic bug per entry, each edit's text occurs once.
Written before the tests that kill them (issue 24), aimed first at what no test data exercised
(the unix time base, deg/s gyros, a non-zero GNSS latency in the live time map) and at outputs
written but never read back (MAVLink HDOP/VDOP, the observability analysis beyond the rank, score
percentiles and baselines, the waterfall's SNR and band, the sign of the CSV residuals).
"""
from __future__ import annotations

from mutants import MODULES, mutant

MODULES["dataset"] = {
    "files": ["leonav_runtime/dataset/", "leonav_runtime/scoring/errors.py"],
    "tests": ["tests/test_dataset_units_time.py", "tests/test_dataset_import.py", "tests/test_dataset_sources.py",
              "tests/test_dataset_gaps.py"]}
MODULES["nav"] = {
    "files": ["leonav_runtime/nav/"],
    "tests": ["tests/test_nav_outputs_decoded.py", "tests/test_live_outputs.py", "tests/test_nav_units.py"]}
MODULES["observability"] = {
    "files": ["leonav_runtime/observability/"],
    "tests": ["tests/test_observability_information.py", "tests/test_observability.py"]}
MODULES["beacons_signal"] = {
    "files": ["leonav_runtime/beacons/doppler.py", "leonav_runtime/beacons/ridges.py",
              "leonav_runtime/beacons/waterfall.py", "leonav_runtime/beacons/pipeline.py",
              "leonav_runtime/beacons/row_fft.py"],
    "tests": ["tests/test_beacons_signal_outputs.py", "tests/test_beacons_signal.py", "tests/test_row_fft.py"]}
MODULES["base_signal"] = {
    "files": ["leonav_runtime/commands/base.py"],
    "tests": ["tests/test_base_signal_rearm.py", "tests/test_base_loopback.py"]}
MODULES["fix_table"] = {
    "files": ["leonav_runtime/replay/gnss_table.py"],
    "tests": ["tests/test_gnss_table_fields.py", "tests/test_replay.py"]}
MODULES["pcrb_stream"] = {
    "files": ["leonav_runtime/sweep/montecarlo.py", "leonav_runtime/sweep/run.py"],
    "tests": ["tests/test_pcrb_records.py"]}

# ---------------------------------------------------------------- dataset (+ scoring/errors.py)
TB, IMU, GNS = "leonav_runtime/dataset/timebase.py", "leonav_runtime/dataset/imu_read.py", "leonav_runtime/dataset/gnss_read.py"
SPEC, ERR = "leonav_runtime/dataset/spec.py", "leonav_runtime/scoring/errors.py"
mutant("dataset-01", TB, "unix time base read as GPS seconds (leap seconds applied)",
       ('if base == "unix" or base == "first_fix":', 'if base == "first_fix":'),
       ('if base == "gps_seconds":', 'if base in ("gps_seconds", "unix"):'))
mutant("dataset-02", IMU, "single-file IMU: gyro unit not applied (deg/s read as rad/s)",
       ('vals = np.hstack([vals[:, :3] * GYRO_UNITS[s["gyro_unit"]],', 'vals = np.hstack([vals[:, :3],'))
mutant("dataset-03", SPEC, "deg/s converted with 180/pi", ('"deg/s": math.pi / 180}', '"deg/s": 180 / math.pi}'))
mutant("dataset-04", IMU, "two-file IMU: gyro unit not applied",
       ('GYRO_UNITS[s["gyro_unit"]],\n                                   s["gyro_range_radps"])',
        '1.0,\n                                   s["gyro_range_radps"])'))
mutant("dataset-05", TB, "boot clock pair applied the wrong way round", ("t - pair[0] + pair[1]", "t - pair[1] + pair[0]"))
mutant("dataset-06", TB, "single-week GPS time of week: Sunday rollover not followed", ("weeks += np.cumsum(falls)", "pass"))
mutant("dataset-07", IMU, "FRD -> FLU flips only the down axis", ("out[:, 1:] *= -1.0", "out[:, 2:] *= -1.0"))
mutant("dataset-08", GNS, "msl heights: geoid separation subtracted",
       ('h = v[:, 3] + (g["geoid_separation_m"]', 'h = v[:, 3] - (g["geoid_separation_m"]'))
mutant("dataset-09", GNS, "NAV-PVT velocity: Up not negated from Down", ("v.append((e, n, -d))", "v.append((e, n, d))"))
mutant("dataset-10", GNS, "RMC velocity: East and North swapped",
       ("return key, (speed * math.sin(c), speed * math.cos(c))", "return key, (speed * math.cos(c), speed * math.sin(c))"))
mutant("dataset-11", GNS, "RMC speed in statute miles per hour", ("KNOT_MPS = 1852.0 / 3600.0", "KNOT_MPS = 1609.344 / 3600.0"))
mutant("dataset-12", ERR, "horizontal p95 is the 90th percentile", ('"horizontal_p95_m": q(95)', '"horizontal_p95_m": q(90)'))
mutant("dataset-13", ERR, "hold-last-fix baseline holds the previous fix at a fix epoch",
       ('k = np.searchsorted(fixes.t, t, side="right") - 1\n    out = np.full((t.size, 3), np.nan)',
        'k = np.searchsorted(fixes.t, t, side="left") - 1\n    out = np.full((t.size, 3), np.nan)'))
mutant("dataset-14", "leonav_runtime/dataset/scoring.py", "interpolated-fix baseline extrapolates past the fixes",
       ("    out[(t < fixes.t[0]) | (t > fixes.t[-1])] = np.nan\n", ""))
mutant("dataset-15", ERR, "vertical RMSE over the horizontal columns", ('"rmse_vertical_m": rms(e[:, 2:])', '"rmse_vertical_m": rms(e[:, 1:])'))
mutant("dataset-16", SPEC, "accelerometer unit g = 9.81", ('"g": 9.80665}', '"g": 9.81}'))

# ---------------------------------------------------------------- nav: live time map, IMU timing, outputs
TM, MAV, NMO = "leonav_runtime/nav/timemap.py", "leonav_runtime/nav/sinks/mavlink_out.py", "leonav_runtime/nav/sinks/nmea_out.py"
SOL = "leonav_runtime/nav/sinks/solution.py"
mutant("nav-01", TM, "GNSS output latency subtracted from the time map",
       ("self.late_s = self.tag_serialization_s() + self.gnss_latency_s", "self.late_s = self.tag_serialization_s() - self.gnss_latency_s"))
mutant("nav-02", TM, "GNSS output latency ignored", ("self.gnss_latency_s = float(gnss_latency_s)", "self.gnss_latency_s = 0.0"))
mutant("nav-03", TM, "tag sentence length without CR LF",
       ("len(rec.text) + NMEA_LINE_END_BYTES)", "len(rec.text))"))
mutant("nav-04", TM, "mapped time moved back by the tag's serialization", ("return float(self.map.to_utc_unix(t_mono_s)) + self.late_s",
                                                                          "return float(self.map.to_utc_unix(t_mono_s)) - self.late_s"))
mutant("nav-05", MAV, "MAVLink HDOP = sigma_h * 1.5", ("hdop = sol.sigma_horizontal_m / 1.5", "hdop = sol.sigma_horizontal_m * 1.5"))
mutant("nav-06", MAV, "MAVLink VDOP is the vertical sigma itself", ("float(hdop), float(sig_u / 1.5),", "float(hdop), float(sig_u),"))
mutant("nav-07", MAV, "MAVLink velocity north and east swapped", ("float(vn), float(ve), float(-vu)", "float(ve), float(vn), float(-vu)"))
mutant("nav-08", MAV, "MAVLink vd = +up", ("float(vn), float(ve), float(-vu)", "float(vn), float(ve), float(vu)"))
mutant("nav-09", MAV, "MAVLink horizontal and vertical accuracy swapped",
       ("float(sol.sigma_horizontal_m), float(sig_u), int(min(", "float(sig_u), float(sol.sigma_horizontal_m), int(min("))
mutant("nav-10", MAV, "MAVLink yaw of due north sent as 0 (= no yaw)",
       ("yaw_cdeg = int(round(sol.heading_deg * 100.0)) or 36000", "yaw_cdeg = int(round(sol.heading_deg * 100.0))"))
mutant("nav-11", MAV, "MAVLink GPS time without leap seconds",
       ("t_gps = utc_to_gps_seconds(sol.utc)", "t_gps = sol.utc.timestamp() - 315964800.0"))
mutant("nav-12", NMO, "GST north and east sigmas swapped", ("nmea_write.gst(sol.utc, n, e, u,", "nmea_write.gst(sol.utc, e, n, u,"))
mutant("nav-13", SOL, "heading = yaw - 90 deg", ("return (90.0 - math.degrees(self.rpy_rad[2])) % 360.0",
                                                 "return (math.degrees(self.rpy_rad[2]) - 90.0) % 360.0"))
mutant("nav-14", NMO, "PLNAV roll and pitch swapped",
       ("roll, pitch = (math.degrees(a) for a in sol.rpy_rad[:2])", "pitch, roll = (math.degrees(a) for a in sol.rpy_rad[:2])"))
mutant("nav-15", MAV, "GLOBAL_POSITION_SENSOR accuracies swapped",
       ("float(sol.h_m), float(sol.h_m), float(sol.sigma_horizontal_m), float(sig_u))",
        "float(sol.h_m), float(sol.h_m), float(sig_u), float(sol.sigma_horizontal_m))"))
mutant("nav-16", "leonav_runtime/nav/imu_timing.py", "IMU sample times: packet serialization added, not removed",
       ("return [float(t) - self.serial_s for t in", "return [float(t) + self.serial_s for t in"))

# ---------------------------------------------------------------- observability
GR, REP = "leonav_runtime/observability/gramian.py", "leonav_runtime/observability/report.py"
mutant("observability-01", GR, "measurement rows weighted by 1/R instead of 1/sqrt(R)",
       ("rows.append((H @ Phi / math.sqrt(var))[None, :])", "rows.append((H @ Phi / var)[None, :])"))
mutant("observability-02", GR, "information scaled by 1/S instead of S",
       ("A = np.linalg.solve(acc.Phi[k].T, acc.R[k].T).T * scales[None, :]", "A = np.linalg.solve(acc.Phi[k].T, acc.R[k].T).T / scales[None, :]"))
mutant("observability-03", GR, "index without the square of the singular values",
       ("index[k] = 1.0 - np.sum(Vt**2 / (1.0 + sv[:, None] ** 2), axis=0)", "index[k] = 1.0 - np.sum(Vt**2 / (1.0 + sv[:, None]), axis=0)"))
mutant("observability-04", GR, "rank with an absolute tolerance", ("r = int(np.sum(sv > rel_tol * sv[0])) if sv[0] > 0 else 0",
                                                                 "r = int(np.sum(sv > rel_tol)) if sv[0] > 0 else 0"))
mutant("observability-05", GR, "target reached at the first output time reported as never",
       ("time_to = np.array([acc.t_s[f] if f >= 0 else np.inf for f in first])", "time_to = np.array([acc.t_s[f] if f > 0 else np.inf for f in first])"))
mutant("observability-06", GR, "condition number inverted", ("cond[k] = sv[0] / sv[-1]", "cond[k] = sv[-1] / sv[0]"))
mutant("observability-07", GR, "weakest direction's information is the singular value, not its square",
       ('weakest.append({"information": float(sv[i] ** 2), "unobservable": False,', 'weakest.append({"information": float(sv[i]), "unobservable": False,'))
mutant("observability-08", GR, "sigma_info in scaled units (not multiplied back by S)",
       ("sig[k] = _sigma_info(Vt, sv, vague) * scales", "sig[k] = _sigma_info(Vt, sv, vague)"))
mutant("observability-09", GR, "measurement with non-finite aux not skipped",
       ("if not (var > 0 and math.isfinite(var) and np.all(np.isfinite(rec[\"aux\"]))):", "if not (var > 0 and math.isfinite(var)):"))
mutant("observability-10", GR, "IMU records linearised at their end", ('k = np.where(recs["kind"] < 0, k - 1, k)', "k = k"))
mutant("observability-11", GR, "random-walk parameters keep their noise", ('if name in ("vrw", "arw") or name.endswith("_rw") or name.startswith("q_"):',
                                                                          'if name in ("vrw", "arw") or name.startswith("q_"):'))
mutant("observability-12", GR, "a target on a block sets only its first component", ("tgt[hit] = float(value)", "tgt[hit[0]] = float(value)"))
mutant("observability-13", REP, "CSV rank and n_states swapped", ('rows.append([s["mode"], s["motion"], s["rank"], s["n_states"],',
                                                                 'rows.append([s["mode"], s["motion"], s["n_states"], s["rank"],'))

# ---------------------------------------------------------------- beacons: doppler, ridges, waterfall, pipeline
DOP, RID = "leonav_runtime/beacons/doppler.py", "leonav_runtime/beacons/ridges.py"
WF, PIP = "leonav_runtime/beacons/waterfall.py", "leonav_runtime/beacons/pipeline.py"
RFFT = "leonav_runtime/beacons/row_fft.py"
mutant("beacons_signal-01", WF, "band kept twice as wide (|f| <= band)", ("keep = np.abs(f) <= cfg.band_hz / 2", "keep = np.abs(f) <= cfg.band_hz"))
mutant("beacons_signal-02", WF, "noise mean = median * ln 2 (SNR off by 3.2 dB)", ("return self.noise_median / _LN2", "return self.noise_median * _LN2"))
mutant("beacons_signal-03", WF, "hop from the overlap instead of 1 - overlap",
       ("max(1, int(round(n * (1.0 - overlap))))", "max(1, int(round(n * overlap)))"))
mutant("beacons_signal-04", WF, "slice time at its start, not its centre", ("t = (start + np.arange(ns) * hop + n / 2) / sample_rate_hz",
                                                                          "t = (start + np.arange(ns) * hop) / sample_rate_hz"))
mutant("beacons_signal-05", RID, "peak SNR in 20 log10 of the power", ("snr_peak = (10 * np.log10(power / blk.noise_mean[rows]))",
                                                                     "snr_peak = (20 * np.log10(power / blk.noise_mean[rows]))"))
mutant("beacons_signal-06", DOP, "window SNR is the whole ridge's median", ("rows.append((tk, *fit, float(np.median(ridge.snr_db[sel]))))",
                                                                          "rows.append((tk, *fit, float(np.median(ridge.snr_db))))"))
mutant("beacons_signal-07", DOP, "fit variance divided by n (no degrees of freedom)", ("s2 = float(res @ res) / (n - degree - 1)", "s2 = float(res @ res) / n"))
mutant("beacons_signal-08", DOP, "rate sigma from the Doppler's variance", ("float(coef[1]), float(np.sqrt(cov[1, 1])), n", "float(coef[1]), float(np.sqrt(cov[0, 0])), n"))
mutant("beacons_signal-09", DOP, "outlier pass dropped (40 sigma)", ("good = np.abs(res) <= max(4.0 * robust_sigma, 1e-9)", "good = np.abs(res) <= max(40.0 * robust_sigma, 1e-9)"))
mutant("beacons_signal-10", DOP, "window fill checked against a fraction, not the expected points",
       ("if fit is None or fit[4] < min_fill * expected:", "if fit is None or fit[4] < min_fill:"))
mutant("beacons_signal-11", PIP, "measurement CSV residual = predicted - measured",
       ("pr[k], m.rate_hz_s[k] - pr[k], m.snr_db[k]", "pr[k], pr[k] - m.rate_hz_s[k], m.snr_db[k]"))
mutant("beacons_signal-12", PIP, "associations CSV residual adds the removed drift",
       ("resid = m0.rate_hz_s[k] - drift - pr0[k]", "resid = m0.rate_hz_s[k] + drift - pr0[k]"))
mutant("beacons_signal-13", PIP, "summary residual statistics without the absolute value", ("v = np.abs(np.asarray(values, float))", "v = np.asarray(values, float)"))
mutant("beacons_signal-14", PIP, "summary slice duration from the hop", ('"slice_s": res.stft.fft_size / fs', '"slice_s": res.stft.hop / fs'))
mutant("beacons_signal-15", PIP, "measurement CSV lo_offset of the association, not of the capture's LO at the epoch",
       ("lo_t = lo.at(m.t_s) if np.isfinite(lo.offset_hz) else", "lo_t = np.full(m.t_s.size, a.lo_offset_hz) if np.isfinite(lo.offset_hz) else"))
mutant("beacons_signal-16", RID, "ridges shorter than min_duration kept", ("keep = [r for r in ridges if r.duration_s >= self.cfg.min_duration_s]",
                                                                         "keep = [r for r in ridges if r.duration_s >= 0.0]"))
mutant("beacons_signal-17", RID, "a plateau of equal bins gives no peak (> on both sides)",
       ("i = i[(v >= flat[i - 1]) & (v > flat[i + 1])]", "i = i[(v > flat[i - 1]) & (v > flat[i + 1])]"))
mutant("beacons_signal-18", RID, "births weakest first", ("for i in fr[np.argsort(-np.asarray(power, self._power_dtype)[fr])].tolist():",
                                                        "for i in fr[np.argsort(np.asarray(power, self._power_dtype)[fr])].tolist():"))
mutant("beacons_signal-19", RID, "a refused birth (and the one that takes the last free slot) does not mark its side lobes", ("            _take_side_lobes(taken, pk, pk[i], excl)",
                                                                               "            _take_side_lobes(taken, pk, pk[i] if room > 0 else -10**9, excl)"))
mutant("beacons_signal-20", RID, "rate fitted over the last second plus one point", ("i0 = bisect_left(t, t[-1] - span_s, max(0, n - 256))",
                                                                                  "i0 = max(0, bisect_left(t, t[-1] - span_s, max(0, n - 256)) - 1)"))
mutant("beacons_signal-21", WF, "the block after a join starts one sample late",
       ("block, buf_start = block[advance:], buf_start + k * hop", "block, buf_start = block[advance + 1:], buf_start + k * hop"))
mutant("beacons_signal-22", WF, "a hop longer than the FFT: the samples between slices are not skipped across blocks",
       ("            skip = max(0, ns * hop - buf.size)\n", ""))
mutant("beacons_signal-23", RFFT, "the extension called for the inverse transform (the check then hands every FFT to scipy.fft)",
       ("return ext.c2c(frames, (frames.ndim - 1,), True, 0, frames, workers)",
        "return ext.c2c(frames, (frames.ndim - 1,), False, 0, frames, workers)"))
mutant("beacons_signal-24", RFFT, "the extension loaded from its file is not registered: a later import of scipy.fft initialises it again",
       ("    sys.modules[_NAME] = ext\n", ""))

BASE_CMD, FIXTAB = "leonav_runtime/commands/base.py", "leonav_runtime/replay/gnss_table.py"
mutant("base_signal-01", BASE_CMD, "one raise per signal during the build: a library's bare except swallows it and the build runs to its end",
       ("                signal.setitimer(signal.ITIMER_REAL, REARM_S, REARM_S)\n", "                pass\n"))
mutant("base_signal-02", BASE_CMD, "a build that fails after a signal reports that failure (exit 1) instead of the signal",
       ("            if stop:        # failed on", "            if False:        # failed on"))
mutant("fix_table-01", FIXTAB, "a GST/RMC with an unreadable time or value skipped without being counted",
       ("                unreadable += 1       # this epoch", "                pass       # this epoch"))
mutant("fix_table-02", FIXTAB, "pynmea2's text for an unreadable time taken as a time (the crash on hour 25)",
       ("    tod = time_field(msg)               # BadField", "    tod = msg.timestamp               # BadField"))
MC = "leonav_runtime/sweep/montecarlo.py"
mutant("pcrb_stream-01", MC, "the PCRB of every count on the first count's records (a template looked up by mode only)",
       ("    rec = trial_block.template(setup, nav, mode, count).rec.view()",
        '    rec = trial_block.template(setup, nav, mode, setup.scn.starlink["counts"][0]).rec.view()'))
mutant("pcrb_stream-02", MC, "the PCRB's records handed out writable: a caller's edit reaches every later trial",
       ("    rec.flags.writeable = False\n", ""))
mutant("pcrb_stream-03", MC, "the bound builds a template under a realism switch (kept with the setup, 61 MB a point)",
       ("    if not trial_block.uses_template(setup.scn):\n        return simulate.trial_records(",
        "    if False:\n        return simulate.trial_records("))
mutant("pcrb_stream-04", "leonav_runtime/sweep/run.py", "the sweep builds every template under a realism switch, for nothing",
       ("    if not trial_block.uses_template(scn):\n        return 0\n", ""))
