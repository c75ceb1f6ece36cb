"""skyfield with the same Earth orientation table as leonav (independent frame chain).

skyfield reads UT1-UTC and polar motion from a `finals2000A.all` file; we hand it the
table leonav uses (`orbits.eop.default_path()`), so a comparison isolates everything but
the EOP values themselves: IAU-2000 precession-nutation and ITRS on skyfield's side,
GMST-82 TEME -> ECEF on ours.
"""
from __future__ import annotations

import functools
import tempfile
from pathlib import Path


@functools.lru_cache(maxsize=1)
def skyfield_timescale_same_eop():
    from skyfield.api import Loader
    from skyfield.data import iers

    from leonav_runtime.orbits.eop import default_path

    table = default_path()
    folder = Path(tempfile.mkdtemp(prefix="leonav-eop-"))
    (folder / "finals2000A.all").symlink_to(table)
    ts = Loader(str(folder), verbose=False).timescale(builtin=False)
    with open(table, "rb") as f:
        iers.install_polar_motion_table(ts, iers.parse_x_y_dut1_from_finals_all(f))
    return ts
