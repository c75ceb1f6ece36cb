"""Replay a recorded session through the generated filter: fix+imu, leo-alpha+imu, fix+leo-alpha+imu,
and the tightly coupled pseudorange+imu, pseudorange+leo-alpha+imu (`gnss_raw.py`, on request).

Pipeline (`replay_session`), one module per step:
1. `hardware.session.decode_session` re-decodes gnss.raw / imu.raw with their chunk stamps.
2. `timebase.py`: one time axis, the host monotonic stamps mapped to UTC by the session's
   GNSS time map (RMC/NAV-PVT tags; without tags, the host wall clock of session.json,
   flagged in `notes`). t = 0 is the first IMU sample; every record time is s since it.
3. `timebase.py`: the IMU table (WitMotion sample times fitted on their index; mean rates
   over each interval -> increments, body FLU) and the WT901 profile plus quantization noise.
4. `gnss_table.py`: GNSS fixes (GGA/NAV-PVT, sigmas from GST/NAV-PVT/HDOP) -> ENU fix table.
5. `beacon_table.py`: the beacon pipeline on sdr.cu8 -> Doppler-rate table with SGP4
   satellite states, carrier f_c from the capture's RF centre.
6. `run.py`: the tables go the one road into the filter (`leonav_runtime.inputs.assemble`):
   records (Doppler-rate aux and R as in the simulator: averaged specific force and its
   noise), start at the first usable fix (`inputs.FirstFixPrior`: position and velocity of
   the fix, roll/pitch from the WitMotion angles, yaw from `--yaw-deg` or the sensor), P0
   from `inputs.prior_sigmas`; every mode runs on the same inputs.
7. `scoring.py`: errors against truth.csv when present (synthetic sessions), else the GNSS
   fixes (position only; then fix+imu is compared with its own input, which flatters it);
   `report.py`/`plots.py`: metrics.json, CSVs, PNGs.
`direct.py` runs a synthetic session's floats through the same road without the bytes.
"""
from __future__ import annotations

from leonav_runtime.common.lazy_exports import lazy_exports

# names per module, imported on first use (lazy_exports.py): the parser of `leonav replay` and
# commands that need only the mode names do not import the beacon pipeline, simulator or SciPy
__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "beacon_table": ("BeaconMeasurements", "beacon_measurements", "capture_carrier", "doppler_rate_table"),
    "direct": ("compare_replay_direct", "direct_inputs"),
    "gnss_table": ("DEFAULT_UERE_M", "fix_height_m", "fix_table", "usable_fix"),
    "options": ("ALL_MODES", "MODE_ALIASES", "MODES", "ReplayOptions", "replay_mode", "replayable", "uses_raw_gnss",
                "canonical_modes", "check_options"),
    "report": ("write_outputs",),
    "run": ("SessionInputs", "decode_inputs", "replay_session", "run_modes", "session_inputs", "skip_reasons"),
    "scoring": ("Reference", "evaluate", "fix_reference", "mode_metrics", "truth_reference"),
    "timebase": ("filter_profile", "imu_table", "mono_to_utc_function", "regular_sample_times"),
})
