"""Golden replay run: one seeded trial of the paper scenario, kept as a committed CSV.

Any behavioural change of the models, the generated code, the driver or the simulator
shows up as a difference against `tests/data/golden_run.csv` (PX4's practice). After an
intended change, regenerate and commit the new file:

    python -m tests.golden_run --update
"""
from __future__ import annotations

import argparse
import copy
import csv
from pathlib import Path

import numpy as np

GOLDEN = Path(__file__).with_name("data") / "golden_run.csv"
MODE, COUNT, TRIAL = "gps+leo-alpha+imu", 10, 0
COLUMNS = ["t_s", "e_m", "n_m", "u_m", "ve_mps", "vn_mps", "vu_mps", "qw", "qx", "qy", "qz",
           "c_dt_m", "b_lo_hz", "sd_e_m", "sd_n_m", "sd_u_m"]


def golden_rows() -> list[list[float]]:
    """The run: paper scenario shortened to 6 s, 10 Starlink satellites, trial 0, 1 Hz rows."""
    from leonav_runtime.simulation import simulate
    from leonav_runtime.sweep import montecarlo as mc
    from leonav_runtime.core.filter import EKF
    from leonav_runtime.scenarios.load import load_scenario, scenario_from_dict

    raw = copy.deepcopy(load_scenario("paper").raw)
    raw["time"]["duration_s"] = 6.0
    raw["starlink"]["counts"] = [COUNT]
    scn = scenario_from_dict(raw, source="<golden>")
    setup, nav = mc.setup_for(scn)
    trial = simulate.trial_records(setup, MODE, COUNT, mc.trial_rng(scn.seed, TRIAL), nav)
    res = EKF(trial.x0, setup.P0, setup.params, gate=scn.filter["gate_nis"], library=nav.library).run(trial.records)
    rows, _ = mc.eval_rows(trial.records, setup.t_imu, 1.0, scn.imu_rate_hz)
    L = nav.layout
    out = []
    for i in rows:
        x, sd = res.x[i], np.sqrt(res.P_diag[i])
        out.append([float(res.t[i]), *x[L.X_P_ENU_SLICE], *x[L.X_V_ENU_SLICE], *x[L.X_Q_NB_SLICE],
                    x[L.X_C_DT], x[L.X_B_LO], *sd[L.DX_DP_SLICE]])
    return out


def read_golden() -> list[list[float]]:
    with GOLDEN.open() as fh:
        reader = csv.reader(fh)
        assert next(reader) == COLUMNS
        return [[float(v) for v in row] for row in reader]


def write_golden(rows: list[list[float]]) -> None:
    GOLDEN.parent.mkdir(parents=True, exist_ok=True)
    with GOLDEN.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(COLUMNS)
        writer.writerows([[f"{v:.12g}" for v in row] for row in rows])


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--update", action="store_true", help="rewrite tests/data/golden_run.csv")
    if ap.parse_args().update:
        write_golden(golden_rows())
        print(f"wrote {GOLDEN}")
