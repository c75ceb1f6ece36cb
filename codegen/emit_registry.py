"""`gen/registry.py`: the model registry as plain data for the runtime (it never imports models/).

State blocks (offsets, role, dynamics, prior, truth, test steps), parameters (defaults, scenario
keys), observables (source, mode word, stream, table, noise key, and which state blocks, aux
satellite states and specific force their h reads: found symbolically here), the record
streams in merge order and the paper's modes. The runtime's stream lists, mode parser, priors,
scenario sections of local sensors and the simulator's truth draws are written over this data.
"""
from __future__ import annotations

import dataclasses

import casadi as ca

from leonav.models import registry as R
from leonav.models import state as S
from leonav.models.modes import PAPER_MODES
from leonav.models.measurements.orbit_jacobian import reads_orbit


def _dyn(d) -> dict:
    return {k: v for k, v in dataclasses.asdict(d).items() if not (v is None or v == "")}


def _reads(o: R.Observable) -> dict:
    x, aux, p = ca.SX.sym("x", S.NX), ca.SX.sym("aux", S.NAUX), ca.SX.sym("p", S.NP)
    h = o.h(x, aux, p)
    blocks = tuple(s.error_name for s in S.STATES if ca.depends_on(h, x[S.X[s.name].slice]))
    ref = any(ca.depends_on(h, aux[S.AUX[n].slice]) for n in ("r_ref_ecef", "v_ref_ecef", "a_ref_ecef"))
    params = tuple(q.name for q in S.PARAMS if ca.depends_on(h, p[S.P[q.name].offset]))
    return {"reads": blocks, "reads_orbit": reads_orbit(h, aux), "reads_ref": ref,
            "reads_specific_force": ca.depends_on(h, aux[S.AUX["f_b"].slice]), "reads_params": params,
            "reads_interval": ca.depends_on(h, aux[S.AUX["dt_phase"].slice])}


def streams() -> tuple[str, ...]:
    """Record streams in merge order: the IMU, then each observable's stream in kind-id order."""
    out = ["imu"]
    for o in S.MEASUREMENTS:
        if o.stream not in out:
            out.append(o.stream)
    return tuple(out)


def registry_py(banner: str) -> str:
    """The text of gen/registry.py."""
    lines = [banner.rstrip("\n"),
             '"""The model registry as data (emitted from models/: state.py and each measurement module\'s',
             "STATES, PARAMS, OBSERVABLES; see models/registry.py for the meaning of every field).",
             '"""',
             "from collections import namedtuple", "",
             'StateBlock = namedtuple("StateBlock", "name error_name offset size error_offset error_size unit error_unit role '
             'dynamics prior truth fd_step typical doc")',
             'Param = namedtuple("Param", "name offset unit default example scenario lo hi doc")',
             'Noise = namedtuple("Noise", "section key default lo hi doc")',
             'Observable = namedtuple("Observable", "kind name suffix unit source token stream table constellation '
             'paper rate_hz noise reads reads_orbit reads_ref reads_specific_force reads_params doc input_noise '
             'reads_interval", defaults=(False, False))', "",
             "STATES = ("]
    for s in S.STATES:
        x, dx = S.X[s.name], S.DX[s.error_name]
        prior = {k: v for k, v in dataclasses.asdict(s.prior).items()
                 if not (v is None or v == "" or (k == "given" and not v))}
        lines.append(f"    StateBlock({s.name!r}, {s.error_name!r}, {x.offset}, {x.size}, {dx.offset}, {dx.size}, "
                     f"{s.unit!r}, {s.err_unit!r}, {s.role!r}, {_dyn(s.dynamics)!r}, {prior!r}, "
                     f"{dataclasses.asdict(s.truth)!r}, {s.fd_step!r}, {s.typical!r}, {s.doc!r}),")
    lines += [")", "", "PARAMS = ("]
    for q in S.PARAMS:
        lines.append(f"    Param({q.name!r}, {S.P[q.name].offset}, {q.unit!r}, {q.default!r}, {q.example!r}, "
                     f"{q.scenario!r}, {q.lo!r}, {q.hi!r}, {q.doc!r}),")
    lines += [")", "", "OBSERVABLES = ("]
    for o in S.MEASUREMENTS:
        noise = "None"
        if o.noise is not None:
            section, _, key = o.noise.key.partition(".")
            noise = (f"Noise({section!r}, {key!r}, {o.noise.default!r}, {o.noise.lo!r}, {o.noise.hi!r}, "
                     f"{o.noise.doc!r})")
        r = _reads(o)
        lines.append(f"    Observable({o.kind_id}, {o.name!r}, {o.suffix!r}, {o.unit!r}, {o.source!r}, {o.token!r}, "
                     f"{o.stream!r}, {o.table!r}, {o.constellation!r}, {o.paper!r}, {o.rate_hz!r}, {noise}, "
                     f"{r['reads']!r}, {r['reads_orbit']!r}, {r['reads_ref']!r}, {r['reads_specific_force']!r}, "
                     f"{r['reads_params']!r}, {o.doc!r}, {o.input_noise!r}, {r['reads_interval']!r}),")
    lines += [")", "",
              f"STREAMS = {streams()!r}",
              '"""Record streams in merge order (at equal t: the IMU first, then this order)."""',
              f"PAPER_MODES = {tuple(PAPER_MODES)!r}",
              '"""The paper\'s fusion modes: the default mode list of every scenario."""', ""]
    return "\n".join(lines)


def _md_table(header: list[str], rows: list[list]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return out + ["| " + " | ".join(str(c) for c in row) + " |" for row in rows] + [""]


def _dyn_text(d) -> str:
    if isinstance(d, R.RandomWalk):
        return ("random walk, PSD " + (d.psd or (f"{d.density}^2" if d.density else f"{d.psd_value:g}")))
    if isinstance(d, R.GaussMarkov):
        return f"Gauss-Markov, rate {d.beta}, density {d.density}"
    if isinstance(d, R.Integral):
        return f"integral of {d.of}, PSD {d.psd}"
    return d.kind


def registry_md(banner: str) -> str:
    """The text of gen/REGISTRY.md: the registry's tables for people (docs/design.md links it)."""
    lines = [banner, "", "# The model registry", "",
             "Generated from models/ (state.py and each measurement module's STATES, PARAMS, OBSERVABLES;",
             "models/registry.py says what every field means). Regenerate with `leonav codegen`.", "",
             "## State blocks (layout order)", ""]
    rows = []
    for s in S.STATES:
        x, dx = S.X[s.name], S.DX[s.error_name]
        prior = (f"{s.prior.value:g}" if s.prior.value is not None else
                 f"profile `{s.prior.profile_field}`" if s.prior.profile_field else "given by the run")
        rows.append([f"`{s.name}`", f"{x.offset}:{x.offset + x.size}", f"`{s.error_name}` {dx.offset}:{dx.offset + dx.size}",
                     s.err_unit, s.role, _dyn_text(s.dynamics), prior, f"{s.truth.start}, {s.truth.stream}", s.doc])
    lines += _md_table(["block", "x", "dx", "unit", "role", "dynamics", "prior sigma", "truth (start, stream)",
                        "meaning"], rows)
    lines += ["## Parameters p", ""]
    lines += _md_table(["name", "offset", "unit", "default", "scenario key", "meaning"],
                       [[f"`{q.name}`", S.P[q.name].offset, q.unit, "-" if q.default is None else f"{q.default:g}",
                         f"`{q.scenario}`" if q.scenario else "", q.doc] for q in S.PARAMS])
    lines += ["## Observables (kind-id order)", ""]
    rows = []
    for o in S.MEASUREMENTS:
        r = _reads(o)
        noise = f"`{o.noise.key}` = {o.noise.default:g}" if o.noise else "with the data"
        rows.append([o.kind_id, f"`{o.name}`", o.unit, o.source, f"`{o.token}`", o.stream, o.table,
                     o.constellation or "", "yes" if o.paper else "", noise, ", ".join(r["reads"]), o.doc])
    lines += _md_table(["kind", "name", "unit", "source", "mode word", "stream", "table", "satellites", "paper",
                        "sigma", "reads", "meaning"], rows)
    lines += ["## Modes", "", "The paper's (every scenario's default): " + ", ".join(f"`{m}`" for m in PAPER_MODES)
              + ". Any other is named by its words (models/modes.py).", "",
              "## Sections of local sensors (scenario and dataset description)", ""]
    for token in dict.fromkeys(o.token for o in S.MEASUREMENTS if o.table == "local"):
        obs = [o for o in S.MEASUREMENTS if o.token == token]
        n = obs[0].noise
        keys = [["`rate_hz`", "Hz", f"{obs[0].rate_hz:g}", "scenario: sample rate of the simulated sensor"],
                [f"`{n.key.split('.', 1)[1]}`", n.key.rsplit("_", 1)[-1], f"{n.default:g}", n.doc]]
        keys += [[f"`{q.scenario.split('.', 1)[1]}`", q.scenario.rsplit("_", 1)[-1],
                  f"{q.default:g}", q.doc] for q in S.PARAMS if q.scenario.startswith(token + ".")]
        keys += [["`file`, `columns`, `time_column`, `time_unit`, `delimiter`", "-", "",
                  "dataset description: the CSV and its columns (" + ", ".join(o.suffix for o in obs) + ")"]]
        lines += [f"### [{token}]", ""] + _md_table(["key", "unit", "default", "meaning"], keys)
    return "\n".join(lines)
