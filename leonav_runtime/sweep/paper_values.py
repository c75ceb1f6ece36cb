"""Values the paper reports for its simulation (Fig. "Performance in simulation and lower
bound" and its text), in SI units, shared by the findings check and the figures."""
from __future__ import annotations

# (low, high) 3D position RMSE band at the largest Starlink count of the static run, m
PAPER_FINDINGS = {
    "gps_aided_position_m": (1.0, 2.0),
    "leo_alpha_position_m": (6.0, 9.0),
}
