"""Emit the model's plain data for the runtime: constants and sensor profiles.

The runtime never imports `models/`; what it needs of the model besides the compiled
functions (named constants, IMU and clock noise profiles) is written here as Python and
C text into `leonav_runtime/gen/`, values in `repr` form so they round-trip exactly.
"""
from __future__ import annotations

import dataclasses
import math

from leonav.models import clock as model_clock
from leonav.models import imu as model_imu
from leonav.models.constants import CONSTANTS


def constants_py(banner: str) -> str:
    """`gen/constants.py`: every named constant with its unit and meaning as a docstring."""
    lines = [banner.rstrip("\n"), '"""Named constants of leonav (emitted from models/constants.py). SI unless the unit says."""', ""]
    for c in CONSTANTS:
        lines.append(f"{c.name} = {c.value!r}")
        lines.append(f'"""{c.unit}: {c.doc}"""')
        lines.append("")
    return "\n".join(lines)


def constants_h(banner: str) -> str:
    """`gen/constants.h`: the same constants as C macros (`LEONAV_<NAME>`)."""
    lines = [banner.rstrip("\n"), "#ifndef LEONAV_CONSTANTS_H", "#define LEONAV_CONSTANTS_H", ""]
    for c in CONSTANTS:
        lines.append(f"#define LEONAV_{c.name} ({c.value!r})  /* {c.unit}: {c.doc} */")
    lines += ["", "#endif  /* LEONAV_CONSTANTS_H */", ""]
    return "\n".join(lines)


def _dataclass_source(cls) -> list[str]:
    lines = ["@dataclass(frozen=True)", f"class {cls.__name__}:", f'    """{cls.__doc__.strip()}"""', ""]
    for f in dataclasses.fields(cls):
        default = "" if f.default is dataclasses.MISSING else f" = {_literal(f.default)}"
        lines.append(f"    {f.name}: {f.type}{default}")
    return lines + ["", ""]


def _literal(value) -> str:
    """Python source of a field value (inf and nan as math names: the module imports math)."""
    if isinstance(value, float) and not math.isfinite(value):
        return "math.inf" if value > 0 else ("-math.inf" if value < 0 else "math.nan")
    return repr(value)


def _instance_source(var: str, obj) -> str:
    args = ", ".join(f"{f.name}={_literal(getattr(obj, f.name))}" for f in dataclasses.fields(obj))
    return f"{var} = {type(obj).__name__}({args})"


def profiles_py(banner: str) -> str:
    """`gen/profiles.py`: IMU and clock noise profiles (SI) as frozen dataclasses."""
    lines = [banner.rstrip("\n"),
             '"""IMU and receiver-clock noise profiles (emitted from models/imu.py and models/clock.py).',
             "",
             "Units: vrw m/s/sqrt(s), arw rad/sqrt(s), acc_bias_rw m/s^2/sqrt(s), gyro_bias_rw",
             "rad/s/sqrt(s), acc_bias_sigma m/s^2, gyro_bias_sigma rad/s; q_cdt m^2/s, q_cddt m^2/s^3.",
             'Sources are in each profile\'s `source` field."""',
             "from __future__ import annotations", "", "import math", "from dataclasses import dataclass", "", ""]
    lines += _dataclass_source(model_imu.ImuProfile)
    lines += _dataclass_source(model_clock.ClockProfile)
    imu_names = []
    for name, prof in model_imu.PROFILES.items():
        var = name.upper()
        imu_names.append((name, var))
        lines.append(_instance_source(var, prof))
    lines.append(_instance_source("TCXO", model_clock.TCXO))
    lines.append("")
    lines.append("IMU_PROFILES = {" + ", ".join(f"{n!r}: {v}" for n, v in imu_names) + "}")
    lines.append('CLOCK_PROFILES = {"tcxo": TCXO}')
    lines.append("")
    return "\n".join(lines)
