"""The registry: what the rest of leonav needs to know about every state block, parameter and
observable, declared once beside its equations.

Pure Python (no casadi). A measurement module in `models/measurements/` declares at its top

    STATES = (StateBlock(...), ...)      # state blocks only this sensor's models read (optional)
    PARAMS = (Param(...), ...)           # parameters of its models (optional)
    OBSERVABLES = (Observable(...), ...) # its observables, each with its h

and `models.state` builds the layout from the mechanization's own blocks followed by every
module's blocks (modules ordered by their first observable's kind id, so a new sensor appends
and no existing offset moves). Everything else is derived: the generated functions, the
process noise and mechanization of each block (`dynamics`), the priors, the simulator's truth
draws, the scenario and dataset sections of local sensors, the runtime's stream and mode lists
(emitted into `leonav_runtime/gen/registry.py`) and the tests' tables.

`check()` validates the whole registry before anything is generated: an inconsistent entry is
one `RegistryError` line naming the entry and the field.
"""
from __future__ import annotations

import importlib
import pkgutil
import re
from dataclasses import dataclass, field
from typing import Callable, Union


class RegistryError(ValueError):
    """An inconsistent registry entry (the message names the entry and the field)."""


# --- dynamics of a state block ------------------------------------------------------------

@dataclass(frozen=True)
class Mechanization:
    """Driven by the strapdown mechanization (position, velocity, attitude)."""

    kind: str = "mechanization"


@dataclass(frozen=True)
class Constant:
    """Constant: no process noise."""

    kind: str = "constant"


@dataclass(frozen=True)
class RandomWalk:
    """Random walk: white derivative of PSD `psd` (a parameter's name, value in unit^2/s), or of
    PSD density^2 (`density`: a parameter in unit/sqrt(s)), or of a fixed PSD `psd_value`."""

    psd: str = ""
    density: str = ""
    psd_value: float | None = None
    kind: str = "random-walk"


@dataclass(frozen=True)
class GaussMarkov:
    """First-order Gauss-Markov: db/dt = -beta b + w, w of PSD density^2; `beta` (1/s) and
    `density` are parameters' names. beta = 0 is the random walk of the same density."""

    beta: str
    density: str
    kind: str = "gauss-markov"


@dataclass(frozen=True)
class Integral:
    """The integral of another block (`of`, the same size) plus white noise of PSD `psd` (a
    parameter): a clock bias integrating its drift. The pair is discretized exactly."""

    of: str
    psd: str
    kind: str = "integral"


Dynamics = Union[Mechanization, Constant, RandomWalk, GaussMarkov, Integral]


# --- prior and truth -------------------------------------------------------------------------

@dataclass(frozen=True)
class Prior:
    """The filter's initial 1-sigma of a block (error-state units): `value` (SI), or an IMU
    profile's field (`profile_field`), or given by the caller (`given`: position, velocity,
    attitude); `doc` says why."""

    value: float | None = None
    profile_field: str = ""
    given: bool = False
    doc: str = ""


@dataclass(frozen=True)
class Truth:
    """How the simulator draws a block's truth: it starts from `start` ('prior': a draw from the
    prior; 'zero'; or a scenario key 'section.key' in the block's unit) and follows its dynamics
    with noise drawn from `stream` ('trial': the trial's random stream, in layout order - the
    blocks of the paper's model, whose draws every earlier result shares; 'own': a stream of
    its own keyed by the block's name, so adding a block never changes another's draws;
    'none': held at its start, for a block no simulated observable reads)."""

    start: str = "prior"
    stream: str = "own"


# --- declarations ---------------------------------------------------------------------------

@dataclass(frozen=True)
class StateBlock:
    """One block of the state. `size` is the nominal size; `error_size` that of its error-state
    block (default the same: only the attitude quaternion differs); `role`: 'navigation' (the 9D,
    mechanized), 'imu' (errors of the propagating sensor, entering through its increments) or
    'measurement' (errors of a measuring sensor, entering through its observables' h).
    `fd_step`: finite-difference step of the error state in tests (SI); `typical`: magnitude of
    a random nominal value in tests (SI)."""

    name: str
    size: int
    unit: str
    doc: str
    dynamics: Dynamics
    prior: Prior
    role: str = "measurement"
    fd_step: float = 0.0
    typical: float = 1.0
    truth: Truth = field(default_factory=Truth)
    error_size: int | None = None
    error_doc: str = ""
    error: str = ""
    error_unit: str = ""

    @property
    def error_name(self) -> str:
        """Name of the error-state block (default 'd' + name)."""
        return self.error or "d" + self.name

    @property
    def err_unit(self) -> str:
        """Unit of the error-state block (default the block's; the attitude's is rad)."""
        return self.error_unit or self.unit

    @property
    def nerr(self) -> int:
        return self.size if self.error_size is None else self.error_size


@dataclass(frozen=True)
class Param:
    """One entry of the parameter vector p. `default`: its value when the run gives none (None:
    the run must give it); `example`: a typical value for tests; `scenario`: 'section.key' of a
    scenario/dataset key that sets it (the key's unit suffix converts: `_deg` -> rad), within
    [lo, hi] in the key's unit; `doc` says where the runtime takes it from."""

    name: str
    unit: str
    doc: str
    default: float | None = None
    example: float = 1.0
    scenario: str = ""
    lo: float | None = None
    hi: float | None = None


@dataclass(frozen=True)
class Noise:
    """The 1-sigma of an observable's measurements as a scenario / dataset key: `section.key`
    (the key names its unit: the observable's, or `_deg` for an angle in rad), default and
    range in the key's unit."""

    key: str
    default: float
    lo: float
    hi: float
    doc: str = ""


SOURCES = ("gnss", "leo", "local", "constraint")
TABLES = ("satellite", "fix", "gnss_obs", "constraint", "local")


@dataclass(frozen=True)
class Observable:
    """One scalar observable. `h(x, aux, p)` its model (symbolic); `source`: gnss (a GNSS
    receiver's satellites or fixes), leo (LEO beacons), local (a sensor on the vehicle) or
    constraint (a motion pseudo-measurement); `token`: its name in mode names (`gps+imu`,
    `leo-alpha+imu`, `gps+imu+baro`); `stream`: the record stream it travels in; `table`: the
    sensor table kind it is read from; `noise`: its sigma key (None: the sigma comes with the
    data); `constellation`: the simulated satellites it uses (satellite observables);
    `paper`: one of the paper's observables; `kind_id`: its record kind, stable (a new
    observable takes the next free one); `rate_hz`: default rate of a simulated local sensor;
    `input_noise`: R is the generated `leonav_doppler_rate_variance` (the beacon's sigma plus the
    accelerometer noise its h reads through aux f_b, models/input_noise.py), not sigma^2."""

    name: str
    suffix: str
    kind_id: int
    h: Callable
    unit: str
    source: str
    token: str
    stream: str
    table: str
    doc: str
    noise: Noise | None = None
    constellation: str = ""
    paper: bool = False
    dim: int = 1
    rate_hz: float = 10.0
    input_noise: bool = False


@dataclass(frozen=True)
class Declarations:
    """What one measurement module declares."""

    module: str
    states: tuple[StateBlock, ...]
    params: tuple[Param, ...]
    observables: tuple[Observable, ...]


# --- discovery -----------------------------------------------------------------------------

MEASUREMENT_PACKAGE = "leonav.models.measurements"
NAME = re.compile(r"[a-z][a-z0-9_]*")


def module_declarations() -> list[Declarations]:
    """Every measurement module's declarations, ordered by its first observable's kind id
    (modules that declare no observable - shared geometry - are skipped)."""
    package = importlib.import_module(MEASUREMENT_PACKAGE)
    out = []
    for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda i: i.name):
        module = importlib.import_module(f"{MEASUREMENT_PACKAGE}.{info.name}")
        obs = tuple(getattr(module, "OBSERVABLES", ()))
        if not obs:
            continue
        out.append(Declarations(info.name, tuple(getattr(module, "STATES", ())), tuple(getattr(module, "PARAMS", ())),
                                obs))
    return sorted(out, key=lambda d: min(o.kind_id for o in d.observables))


def _where(kind: str, name: str, field_name: str) -> str:
    return f"registry: {kind} {name!r}: {field_name}"


def check(states: tuple[StateBlock, ...], params: tuple[Param, ...], observables: tuple[Observable, ...],
          noise_sections: set[str]) -> None:
    """Raise one RegistryError for the first inconsistent entry (module doc)."""
    pnames = [p.name for p in params]
    snames = [s.name for s in states]
    for kind, names in (("state block", snames), ("parameter", pnames), ("observable", [o.name for o in observables])):
        seen = set()
        for n in names:
            if n in seen:
                raise RegistryError(f"{_where(kind, n, 'name')}: declared twice")
            seen.add(n)
    for s in states:
        if not NAME.fullmatch(s.name):
            raise RegistryError(f"{_where('state block', s.name, 'name')}: expected lower_case letters, digits, _")
        if not s.unit:
            raise RegistryError(f"{_where('state block', s.name, 'unit')}: missing")
        if s.size < 1 or s.nerr < 1:
            raise RegistryError(f"{_where('state block', s.name, 'size')}: expected >= 1")
        if s.role not in ("navigation", "imu", "measurement"):
            raise RegistryError(f"{_where('state block', s.name, 'role')}: {s.role!r}: expected navigation, imu "
                                "or measurement")
        pr = s.prior
        if not isinstance(pr, Prior) or (pr.value is None and not pr.profile_field and not pr.given):
            raise RegistryError(f"{_where('state block', s.name, 'prior')}: missing (a value, a profile field or given)")
        if pr.value is not None and not pr.value >= 0:
            raise RegistryError(f"{_where('state block', s.name, 'prior')}: {pr.value!r}: expected a sigma >= 0")
        if not s.fd_step > 0:
            raise RegistryError(f"{_where('state block', s.name, 'fd_step')}: missing (a finite-difference step > 0)")
        d = s.dynamics
        refs = {"psd": getattr(d, "psd", ""), "density": getattr(d, "density", ""), "beta": getattr(d, "beta", "")}
        for key, ref in refs.items():
            if ref and ref not in pnames:
                raise RegistryError(f"{_where('state block', s.name, f'dynamics.{key}')}: unknown parameter {ref!r}")
        if isinstance(d, RandomWalk) and bool(d.psd) + bool(d.density) + (d.psd_value is not None) != 1:
            raise RegistryError(f"{_where('state block', s.name, 'dynamics')}: a random walk needs exactly one of "
                                "psd, density, psd_value")
        if isinstance(d, Integral):
            other = next((o for o in states if o.name == d.of), None)
            if other is None or other.size != s.size:
                raise RegistryError(f"{_where('state block', s.name, 'dynamics.of')}: {d.of!r}: expected a state "
                                    "block of the same size")
        if s.truth.stream not in ("trial", "own", "none"):
            raise RegistryError(f"{_where('state block', s.name, 'truth.stream')}: {s.truth.stream!r}: expected "
                                "trial, own or none")
    ids = sorted(o.kind_id for o in observables)
    if ids != list(range(len(ids))):
        missing = sorted(set(range(len(ids))) - set(ids))
        dup = sorted({i for i in ids if ids.count(i) > 1})
        raise RegistryError(f"registry: observable kind ids: expected 0..{len(ids) - 1} each once "
                            f"({'duplicate ' + str(dup) if dup else 'missing ' + str(missing)})")
    suffixes = set()
    for o in observables:
        where = lambda f: _where("observable", o.name, f)  # noqa: E731
        if not re.fullmatch(r"[A-Z][A-Z0-9_]*", o.name):
            raise RegistryError(f"{where('name')}: expected UPPER_CASE letters, digits, _")
        if o.suffix in suffixes or not NAME.fullmatch(o.suffix):
            raise RegistryError(f"{where('suffix')}: {o.suffix!r}: expected a unique lower_case name")
        suffixes.add(o.suffix)
        if not o.unit:
            raise RegistryError(f"{where('unit')}: missing")
        if o.source not in SOURCES:
            raise RegistryError(f"{where('source')}: {o.source!r}: expected one of {', '.join(SOURCES)}")
        if o.table not in TABLES:
            raise RegistryError(f"{where('table')}: {o.table!r}: expected one of {', '.join(TABLES)}")
        if o.dim != 1:
            raise RegistryError(f"{where('dim')}: {o.dim}: the filter's updates are scalar (1)")
        if not callable(o.h):
            raise RegistryError(f"{where('h')}: not a function h(x, aux, p)")
        if not NAME.fullmatch(o.token) or o.token in ("imu", "leo"):
            raise RegistryError(f"{where('token')}: {o.token!r}: expected a lower_case mode word other than imu, leo")
        if o.table in ("satellite", "local") and o.noise is None:
            raise RegistryError(f"{where('noise')}: missing (a simulated observable needs its sigma key)")
        if o.noise is not None:
            section, _, key = o.noise.key.partition(".")
            if not key or (o.table == "satellite" and section not in noise_sections):
                raise RegistryError(f"{where('noise')}: unknown noise key {o.noise.key!r} (expected section.key, "
                                    f"section one of {', '.join(sorted(noise_sections))} or the sensor's own)")
            if o.table == "local" and section != o.token:
                raise RegistryError(f"{where('noise')}: {o.noise.key!r}: a local sensor's keys live in its own "
                                    f"section [{o.token}]")
            if not o.noise.lo <= o.noise.default <= o.noise.hi or not o.noise.lo > 0:
                raise RegistryError(f"{where('noise')}: default {o.noise.default} outside ({o.noise.lo}, {o.noise.hi}]")
        if o.table == "satellite" and o.constellation not in ("gps", "starlink"):
            raise RegistryError(f"{where('constellation')}: {o.constellation!r}: expected gps or starlink")
    tokens: dict[str, str] = {}
    for o in observables:
        if tokens.setdefault(o.token, o.source) != o.source:
            raise RegistryError(f"{_where('observable', o.name, 'token')}: {o.token!r} is used by observables of "
                                f"another source ({tokens[o.token]}); a mode word names one source")
    for p in params:
        if not NAME.fullmatch(p.name) or not p.unit:
            raise RegistryError(f"{_where('parameter', p.name, 'name/unit')}: expected a lower_case name and a unit")
