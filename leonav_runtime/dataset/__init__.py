"""Real GNSS/INS datasets: a TOML description -> the filter -> scores and trajectory files.

    spec.load_spec(TOML)     files, columns, units, axes, time base, options (validated)
    load.load(spec)          IMU samples (body FLU), GNSS fixes, reference on one time axis
    runner.prepare(dataset)  parameters, coarse alignment, records (inputs.assemble + constraints)
    evaluate.run_dataset     every mode, the outage runs, scores, files (`leonav run`)
"""
from __future__ import annotations

from leonav_runtime.dataset.spec import MODES, DatasetSpec, load_spec, spec_from_dict

__all__ = ["MODES", "DatasetSpec", "load_spec", "spec_from_dict"]
