"""The one road into the filter: sensor tables -> records, x0, P0 and p.

Every source (the simulator, a recorded session's replay, a dataset, live devices) turns
its data into the tables of `tables.py` and calls `assemble`, which returns one
`FilterInputs` for the generated C loop (`leonav_runtime.core.filter.EKF.run`):

    ImuTable, FixTable, VelocityTable, PseudorangeTable, ...      (tables.py: units, frames)
      GnssObservationTable (receiver code / Doppler)              (gnss_obs.py)
      tracked carrier phase -> time differences (phase_differences) (carrier_phase.py)
      + params (filter_params) + Prior | FirstFixPrior           (prior.py)
      -> assemble(...)                                            (assemble.py)
      -> FilterInputs(records per stream, x0, P0, params, notes, counts, init)

Record building lives only here: IMU increments (`imu.py`), GNSS fixes and satellite
observables with their aux and R (`measurements.py`). A new sensor or observable adds a
table and its record function here; nothing else in the runtime changes.
"""
from __future__ import annotations

from leonav_runtime.inputs.assemble import STREAMS, FilterInputs, assemble
from leonav_runtime.inputs.carrier_phase import BREAK_REASONS, PhaseDifferences, phase_differences, tone_to_centre
from leonav_runtime.inputs.consider import OrbitConsider
from leonav_runtime.inputs.gnss_obs import (GNSS_Q_CDDT_M2PS3, GNSS_Q_CDT_M2PS, GNSS_STREAMS,
                                            GnssObservationTable, apply_clock_start, gnss_records)
from leonav_runtime.inputs.imu import F_B_AVERAGE_S, averaged_specific_force, imu_records, latest_sample
from leonav_runtime.inputs.measurements import (aux_blocks, doppler_rate_variance, fix_records, local_records,
                                                satellite_aux, satellite_records, states_from_aux, velocity_records)
from leonav_runtime.inputs.prior import (LO_RANDOM_WALK_HZ2_S, FirstFixPrior, Prior, filter_params, first_fix_prior,
                                         prior_sigmas)
from leonav_runtime.inputs.tables import (SAT_A_MPS2, SAT_R_M, SAT_V_MPS, SATELLITE_TABLES, CarrierPhaseTable,
                                          DopplerRateTable,
                                          DopplerTable, FixTable, ImuTable, LocalSensorTable, OfdmRangeDiffTable,
                                          PseudorangeTable, SatelliteTable, VelocityTable, check_column)

__all__ = [
    "STREAMS", "FilterInputs", "assemble", "OrbitConsider",
    "BREAK_REASONS", "PhaseDifferences", "phase_differences", "tone_to_centre", "CarrierPhaseTable",
    "GNSS_Q_CDDT_M2PS3", "GNSS_Q_CDT_M2PS", "GNSS_STREAMS", "GnssObservationTable", "apply_clock_start", "gnss_records",
    "F_B_AVERAGE_S", "averaged_specific_force", "imu_records", "latest_sample",
    "aux_blocks", "doppler_rate_variance", "fix_records", "local_records", "satellite_aux", "satellite_records", "states_from_aux",
    "velocity_records",
    "LO_RANDOM_WALK_HZ2_S",
    "FirstFixPrior", "Prior", "filter_params", "first_fix_prior", "prior_sigmas",
    "SAT_A_MPS2", "SAT_R_M", "SAT_V_MPS", "SATELLITE_TABLES", "DopplerRateTable", "DopplerTable", "FixTable",
    "ImuTable", "LocalSensorTable", "OfdmRangeDiffTable", "PseudorangeTable", "SatelliteTable", "VelocityTable", "check_column",
]
