"""Structural observability of the error-state filter, from the filter's own symbolic models.

For every mode (a set of observables) and motion class this module builds the discrete-time
local observability matrix of the error-state system along a trajectory of that class,

    O = [H_0; H_1 Phi_0; H_2 Phi_1 Phi_0; ...],   Phi_k = F(x_k, u_k),

with F the error-state transition and H the measurement Jacobians obtained, exactly as for
the generated filter, by differentiating the CasADi models (`models.ekf.nav_transition`,
`models.ekf.nav_h` over `models.measurements.models()`). Row block k stacks one row per
satellite and observable of the mode at step k. O is the Jacobian of the noise-free
measurement sequence h_k(f^k(x_0 [+] dx)) with respect to the initial error dx at 0 (the
discrete counterpart of the Lie-derivative test; `lie_check` verifies this identity by
forward AD through the composed nominal model).

Why discrete time: the models give the filter's mechanization as a one-step map (`mech`),
not a continuous vector field, and the filter propagates its error state with that map's
Jacobian F. Building O from the same F and H means the analysis sees exactly what the
filter sees (including the Earth rate, Coriolis and the gravity model).

The trajectory of each motion class is a generic point: random initial attitude, speed,
heading, turn rate and acceleration (seeded), random non-zero biases, clock and LO offset,
and several satellites in random visible geometry on circular orbits (GNSS orbit radius for
the pseudorange, LEO radius otherwise). IMU increments that realise the motion are solved
for on the generated mechanization itself (Newton on `mech`, as the simulator does), so the
nominal trajectory is exactly a trajectory of the filter's model.

Numerical rank: columns are scaled by a physical unit per state unit (`UNIT_SCALES`), rows by
a nominal noise per observable unit (`NOISE_SCALES`); the rank counts singular values above
`REL_TOL` times the largest, and the decision is reported with its gap (ratio of the smallest
kept to the largest dropped singular value; `MIN_GAP` is required). Null-space directions
are reported as named combinations of error-state components (names from
`models.state.DX_BLOCKS`), in physical units.

The list of error states, their units and the observables are read from `models.state` and
`models.measurements.models()`, and the rows each observable contributes from the aux
entries its model reads, so a new state block, observable or mode needs no change here. Only
what defines a motion or a satellite names a block: position, velocity and attitude of the
nominal state, the aux satellite / reference / specific-force blocks, and `GNSS_OBSERVABLES`
(the observables whose satellites are put on GNSS rather than LEO orbits). The numeric,
run-along analysis (Gramian along a scenario) is `leonav_runtime.observability`; the command
is `leonav observability`.

Modules: settings (scales, thresholds, site, motions), names (components, directions),
symbolic (the CasADi functions), trajectory (generic points), matrix (O and its rank),
analysis (every mode x motion, the Lie check).
"""
from __future__ import annotations

from leonav.codegen.observability.analysis import *  # noqa: F401,F403
from leonav.codegen.observability.analysis import (CaseResult, analyze, analyze_case,  # noqa: F401
                                                   composed_measurements, lie_check, settings)
from leonav.codegen.observability.matrix import *  # noqa: F401,F403
from leonav.codegen.observability.names import *  # noqa: F401,F403
from leonav.codegen.observability.settings import *  # noqa: F401,F403
from leonav.codegen.observability.symbolic import Symbolic, symbolic  # noqa: F401
from leonav.codegen.observability.trajectory import Trajectory, trajectory  # noqa: F401
