"""`leonav codegen new-observable NAME [--bias-state]`: a new sensor as one file.

Writes `models/measurements/NAME.py`: a documented template observable (a scalar local sensor
measuring the IMU's height above the ENU origin, m) with its registry entry - the next free
kind id, its mode word NAME, its record stream, a scenario/dataset section [NAME] with a rate
and a sigma - and, with `--bias-state`, a random-walk bias state `b_NAME` with its parameter.
After `leonav codegen` every part of the system knows it: the generated functions, the layout,
the runtime's streams and modes (`gps+imu+NAME`), the simulator, `leonav observability` and the
tests. Edit `h` (and the entries' units, sigma, prior) to the real sensor.
"""
from __future__ import annotations

import keyword
import re
from pathlib import Path

NAME = re.compile(r"[a-z][a-z0-9_]{0,30}")

TEMPLATE = '''"""{name}: a local sensor's scalar measurement (written by `leonav codegen new-observable {name}`).

    z = p_U{bias_eq}

p_U is the Up coordinate (m) of the IMU in the ENU frame of the run's origin{bias_doc}. This is a
template: write the sensor's model in `h` (from the state x, aux and the parameters p; every
block and parameter by name: models/state.py, `leonav_runtime/gen/REGISTRY.md`), then set the
unit, sigma and rate of its registry entry below{bias_edit}, and run `leonav codegen`. Modes use it
by its word after imu (`gps+imu+{name}`, `leo-alpha+imu+{name}`); a scenario's [{name}] section
sets its rate and sigma, a dataset description's [{name}] section names its file and columns.
"""
from __future__ import annotations

from leonav.models import registry as R
from leonav.models.state import X
{states}

def h(x, aux, p):
    """Predicted {name} measurement (m)."""
    return x[X["p_enu"].offset + 2]{bias_term}


OBSERVABLES = (
    R.Observable("{upper}", "{name}", {kind_id}, h, "m", source="local", token="{name}", stream="{name}",
                 table="local", rate_hz=1.0,
                 noise=R.Noise("{name}.sigma_m", 1.0, 1e-3, 1e3, "1-sigma {name} noise"),
                 doc="{name}: template local sensor (height above the origin)"),
)
'''

STATES = '''
PARAMS = (
    R.Param("{name}_bias_rw", "m/sqrt(s)", "{name} bias random walk", default=0.01, example=0.01),
)
STATES = (
    R.StateBlock("b_{name}", 1, "m", "{name} bias", R.RandomWalk(density="{name}_bias_rw"),
                 R.Prior(1.0, doc="the template's guess: set the sensor's own"), fd_step=1e-2, typical=1.0,
                 error_doc="{name} bias error"),
)
'''


def check_name(name: str, measurements_dir: Path) -> None:
    """A UserInputError-style ValueError unless NAME is a new lower_case module, word and suffix."""
    from leonav.models import state as S

    if not NAME.fullmatch(name) or keyword.iskeyword(name) or name in ("imu", "leo"):
        raise ValueError(f"new-observable {name!r}: expected a lower_case name (letters, digits, _; at most 31), "
                         "not a Python keyword, imu or leo")
    if (measurements_dir / f"{name}.py").exists():
        raise ValueError(f"new-observable {name!r}: {measurements_dir / (name + '.py')} exists")
    taken = {m.suffix for m in S.MEASUREMENTS} | {m.token for m in S.MEASUREMENTS} | {s.name for s in S.STATES}
    if name in taken or f"b_{name}" in taken or name.upper() in {m.name for m in S.MEASUREMENTS}:
        raise ValueError(f"new-observable {name!r}: the name is taken by an observable, mode word or state block")


def render(name: str, bias_state: bool, kind_id: int) -> str:
    """The module text of a new observable."""
    return TEMPLATE.format(
        name=name, upper=name.upper(), kind_id=kind_id,
        states=STATES.format(name=name) if bias_state else "",
        bias_eq=f" + b_{name}" if bias_state else "",
        bias_doc=f", and b_{name} a random-walk bias (state block, parameter `{name}_bias_rw`)" if bias_state else "",
        bias_edit=" and of its bias state" if bias_state else "",
        bias_term=f' + x[X["b_{name}"].offset]' if bias_state else "")


def write(name: str, bias_state: bool = False, measurements_dir: Path | None = None) -> Path:
    """Write models/measurements/NAME.py (module doc); returns its path."""
    from leonav.models import state as S

    from leonav.models import measurements

    folder = Path(measurements_dir) if measurements_dir else Path(next(iter(measurements.__path__)))
    check_name(name, folder)
    path = folder / f"{name}.py"
    path.write_text(render(name, bias_state, max(m.kind_id for m in S.MEASUREMENTS) + 1))
    return path
