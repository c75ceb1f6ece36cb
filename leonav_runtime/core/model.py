"""The runtime's view of the model registry (generated `gen/registry.py`): observables, state
blocks and parameters with everything the runtime needs to know about them, the mode names
and the filter's priors. Every list of states, observables, streams or modes in the runtime is
read from here; none is written by hand. No casadi, no models/.

Mode names (`parse_mode`): `+`-joined mode words of the observables (`registry.Observable.token`),
satellite and GNSS words first, LEO words after the prefix `leo-`, then `imu`, then local
sensors and motion constraints: `gps+imu`, `gps+leo-alpha+imu`, `leo-doppler+alpha+imu`,
`fix+imu+nhc+zupt`, `gps+imu+baro`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterable, Sequence

import numpy as np

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.gen import registry as G

OBSERVABLES = G.OBSERVABLES
STATES = G.STATES
PARAMS = G.PARAMS
STREAMS: tuple[str, ...] = G.STREAMS
"""Record streams in merge order (the IMU's first)."""
PAPER_MODES: tuple[str, ...] = G.PAPER_MODES
"""The paper's fusion modes: every scenario's default mode list."""
_BY_KEY = {**{o.suffix: o for o in OBSERVABLES}, **{o.name: o for o in OBSERVABLES}}
_BLOCKS = {**{s.name: s for s in STATES}, **{s.error_name: s for s in STATES}}
LOCAL_SENSORS: tuple[str, ...] = tuple(dict.fromkeys(o.token for o in OBSERVABLES if o.table == "local"))
"""Mode words of the local sensors (each has its own scenario / dataset section, named so)."""


def observable(key: str):
    """An observable by suffix ('pseudorange') or name ('POS_E')."""
    try:
        return _BY_KEY[key]
    except KeyError:
        raise KeyError(f"unknown observable {key!r}; expected one of {', '.join(o.suffix for o in OBSERVABLES)}") \
            from None


def state_block(name: str):
    """A state block by its nominal ('b_lo') or error-state ('db_lo') name."""
    return _BLOCKS[name]


def stream_observables(stream: str) -> tuple:
    """The observables of a record stream, in kind-id order."""
    return tuple(o for o in OBSERVABLES if o.stream == stream)


def satellite_streams(constellation: str | None = None) -> tuple[str, ...]:
    """Streams of the simulated satellite observables (of one constellation, or all)."""
    return tuple(dict.fromkeys(o.stream for o in OBSERVABLES if o.table == "satellite"
                               and (constellation is None or o.constellation == constellation)))


def simulated(o) -> bool:
    """Whether the scenario simulator produces this observable (satellite and local sensors)."""
    return o.table in ("satellite", "local")


@dataclass(frozen=True)
class Mode:
    """A parsed mode: its name, observables (registry entries, kind-id order), record streams
    (merge order) and the satellite constellations it uses."""

    name: str
    observables: tuple
    streams: tuple[str, ...]

    @property
    def suffixes(self) -> tuple[str, ...]:
        return tuple(o.suffix for o in self.observables)

    @property
    def constellations(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(o.constellation for o in self.observables if o.constellation))

    def uses(self, constellation: str) -> bool:
        return constellation in self.constellations

    @property
    def local_sensors(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(o.token for o in self.observables if o.table == "local"))


def _words(allowed: Callable | None) -> dict[str, tuple]:
    out: dict[str, list] = {}
    for o in OBSERVABLES:
        if allowed is None or allowed(o):
            out.setdefault(o.token, []).append(o)
    return {k: tuple(v) for k, v in out.items()}


def mode_words(allowed: Callable | None = None) -> str:
    """'gps, leo-alpha, ..., imu, baro, ...': the words a mode name may use (for messages)."""
    words = _words(allowed)
    before = [("leo-" if v[0].source == "leo" else "") + k for k, v in words.items() if v[0].source in ("gnss", "leo")]
    after = [k for k, v in words.items() if v[0].source not in ("gnss", "leo")]
    return ", ".join(before + ["imu"] + after)


def parse_mode(name: str, allowed: Callable | None = None, where: str = "mode") -> Mode:
    """The observables and streams of mode `name` (module doc); `allowed(observable)` limits the
    words to what a source can produce. A bad name is a UserInputError naming `where`."""
    words = _words(allowed)

    def bad(problem: str) -> UserInputError:
        return UserInputError(f"{where} {name!r}: {problem}; a mode is +-joined words of {mode_words(allowed)} "
                              "(LEO words after 'leo-', satellite words before imu, local sensors after)")

    parts = name.split("+") if isinstance(name, str) else []
    for word in parts:
        if word != "imu" and (word[4:] if word.startswith("leo-") else word) not in words:
            raise bad(f"unknown word {word!r}")
    if parts.count("imu") != 1:
        raise bad("expected the word imu exactly once")
    i = parts.index("imu")
    chosen: list = []
    leo = False
    for k, word in enumerate(parts):
        if k == i:
            continue
        prefixed = word.startswith("leo-")
        key = word[4:] if prefixed else word
        obs = words.get(key)
        if obs is None:
            raise bad(f"unknown word {word!r}")
        source = obs[0].source
        if k < i:
            if source not in ("gnss", "leo"):
                raise bad(f"{key!r} is a local sensor or constraint: it goes after imu")
            if prefixed and (source != "leo" or leo):
                raise bad(f"{word!r}: 'leo-' starts the LEO words once")
            if source == "leo" and not (leo or prefixed):
                raise bad(f"{word!r}: LEO words follow 'leo-' (e.g. leo-{key})")
            if source == "gnss" and leo:
                raise bad(f"{word!r}: satellite words of GNSS come before the LEO words")
            leo = leo or prefixed
        elif source in ("gnss", "leo") or prefixed:
            raise bad(f"{word!r} is a satellite word: it goes before imu")
        if any(o in chosen for o in obs):
            raise bad(f"{word!r} given twice")
        chosen.extend(obs)
    chosen.sort(key=lambda o: o.kind)
    streams = tuple(s for s in STREAMS if any(o.stream == s for o in chosen))
    return Mode(name, tuple(chosen), streams)


def check_modes(names: Iterable[str], allowed: Callable | None = None, where: str = "mode") -> list[str]:
    """The names in their given order without repeats, each checked (`parse_mode`)."""
    out = list(dict.fromkeys(names))
    for n in out:
        parse_mode(n, allowed, where)
    return out


def prior_sigmas(layout, profile, position_m, velocity_mps, attitude_rad, overrides: dict | None = None) -> np.ndarray:
    """1-sigma of the filter prior per error state (NDX,): the navigation blocks as given
    (scalars or 3-vectors; m, m/s, rad), the IMU biases from the profile, every other block from
    its registry prior; `overrides`: {error-state block name: sigma} (e.g. a scenario's)."""
    given = {"dp": position_m, "dv": velocity_mps, "dtheta": attitude_rad}
    sig = np.zeros(layout.NDX)
    for s in STATES:
        blk = slice(s.error_offset, s.error_offset + s.error_size)
        if overrides and s.error_name in overrides:
            sig[blk] = overrides[s.error_name]
        elif s.prior.get("given"):
            sig[blk] = given[s.error_name]
        elif s.prior.get("profile_field"):
            sig[blk] = getattr(profile, s.prior["profile_field"])
        else:
            sig[blk] = s.prior["value"]
    return sig


def error_slice(name: str) -> slice:
    """The error-state slice of a block (nominal or error name)."""
    s = state_block(name)
    return slice(s.error_offset, s.error_offset + s.error_size)


def measurement_blocks() -> Sequence:
    """The blocks of measuring sensors (clocks, LO, biases of local sensors), layout order."""
    return tuple(s for s in STATES if s.role == "measurement")
