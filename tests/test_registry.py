"""The model registry: one source for every list, checked before anything is generated, and a
new sensor as one file (`leonav codegen new-observable`)."""
from __future__ import annotations

import dataclasses
import importlib.util
import sys

import pytest

from leonav.codegen import cli as codegen_cli
from leonav.codegen import new_observable
from leonav.models import registry as R
from leonav.models import state as S
from leonav_runtime.core import model
from leonav_runtime.gen import registry as REG
from leonav_runtime.gen import state_layout as L


def _check(states=S.STATES, params=S.PARAMS, observables=S.MEASUREMENTS):
    R.check(tuple(states), tuple(params), tuple(observables), S.NOISE_SECTIONS)


def test_the_shipped_registry_is_consistent_and_the_runtime_sees_the_same():
    _check()
    assert [s.name for s in REG.STATES] == [b.name for b in S.X_BLOCKS]
    assert [o.name for o in REG.OBSERVABLES] == [m.name for m in S.MEASUREMENTS] == [m.name for m in L.MEAS_TABLE]
    assert [q.name for q in REG.PARAMS] == L.P_NAMES
    for name in model.PAPER_MODES:   # the paper's modes read only the paper's observables
        assert all(o.paper for o in model.parse_mode(name).observables), name


def _obs(name, **changes):
    return tuple(dataclasses.replace(o, **changes) if o.name == name else o for o in S.MEASUREMENTS)


def _state(name, **changes):
    return tuple(dataclasses.replace(s, **changes) if s.name == name else s for s in S.STATES)


@pytest.mark.parametrize("kwargs, needle", [
    ({"observables": _obs("DOPPLER", noise=R.Noise("starlink.nope", 5.0, 1e-3, 1e4))}, None),
    ({"observables": _obs("DOPPLER", noise=R.Noise("radio.doppler_sigma_hz", 5.0, 1e-3, 1e4))},
     "observable 'DOPPLER': noise: unknown noise key 'radio.doppler_sigma_hz'"),
    ({"observables": _obs("DOPPLER", unit="")}, "observable 'DOPPLER': unit: missing"),
    ({"observables": _obs("DOPPLER", kind_id=7)}, "observable kind ids: expected 0..")]
    + [({"observables": _obs("DOPPLER", source="radio")}, "observable 'DOPPLER': source: 'radio'"),
       ({"observables": _obs("DOPPLER", token="imu")}, "observable 'DOPPLER': token: 'imu'"),
       ({"observables": S.MEASUREMENTS + (dataclasses.replace(S.MEASUREMENTS[0], kind_id=len(S.MEASUREMENTS)),)},
        "observable 'PSEUDORANGE': name: declared twice"),
       ({"states": _state("b_lo", unit="")}, "state block 'b_lo': unit: missing"),
       ({"states": _state("b_lo", prior=R.Prior())}, "state block 'b_lo': prior: missing"),
       ({"states": _state("b_lo", fd_step=0.0)}, "state block 'b_lo': fd_step: missing"),
       ({"states": _state("b_lo", dynamics=R.RandomWalk(psd="q_nothing"))},
        "state block 'b_lo': dynamics.psd: unknown parameter 'q_nothing'"),
       ({"states": _state("c_dt", dynamics=R.Integral(of="b_nothing", psd="q_cdt"))},
        "state block 'c_dt': dynamics.of: 'b_nothing'"),
       ({"states": S.STATES + (S.STATES[-1],)}, f"state block {S.STATES[-1].name!r}: name: declared twice")])
def test_an_inconsistent_entry_is_one_line_naming_it_and_the_field(kwargs, needle):
    if needle is None:   # a sigma key the scenario section does not have is fine: the schema gets it
        _check(**kwargs)
        return
    with pytest.raises(R.RegistryError) as info:
        _check(**kwargs)
    assert needle in str(info.value) and "\n" not in str(info.value)


def test_codegen_stops_on_a_registry_error_before_writing(monkeypatch, tmp_path, capsys):
    from leonav.codegen import generate

    def broken():
        raise R.RegistryError("registry: observable 'X': unit: missing")

    monkeypatch.setattr(generate, "generated_files", broken)
    args = type("A", (), {"action": None, "out": str(tmp_path / "gen"), "check": False})()
    assert codegen_cli.run(args) == 2
    assert capsys.readouterr().err.strip() == "leonav codegen: error: registry: observable 'X': unit: missing"
    assert not (tmp_path / "gen").exists()


def _free_name() -> str:
    """A sensor name no module of the registry uses (this test must pass with any set of sensors)."""
    taken = {m.suffix for m in S.MEASUREMENTS} | {m.token for m in S.MEASUREMENTS} | {s.name for s in S.STATES}
    return next(f"template{k}" for k in range(1000) if f"template{k}" not in taken and f"b_template{k}" not in taken)


@pytest.mark.parametrize("bias", [False, True])
def test_new_observable_template_is_a_valid_registry_entry(tmp_path, bias):
    name = _free_name()
    path = new_observable.write(name, bias, measurements_dir=tmp_path)
    spec = importlib.util.spec_from_file_location("probe_obs_template", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    sys.modules.pop("probe_obs_template", None)
    (obs,) = module.OBSERVABLES
    assert obs.kind_id == len(S.MEASUREMENTS) and obs.token == obs.stream == name and obs.table == "local"
    states = S.STATES + tuple(getattr(module, "STATES", ()))
    params = S.PARAMS + tuple(getattr(module, "PARAMS", ()))
    _check(states, params, S.MEASUREMENTS + (obs,))
    assert (f"b_{name}" in {s.name for s in states}) == bias
    with pytest.raises(ValueError, match="exists"):
        new_observable.write(name, bias, measurements_dir=tmp_path)


@pytest.mark.parametrize("name, needle", [("Baro2", "lower_case"), ("imu", "lower_case"), ("baro", "taken"),
                                          ("class", "keyword")])
def test_new_observable_refuses_a_bad_or_taken_name(tmp_path, name, needle):
    with pytest.raises(ValueError, match=needle):
        new_observable.write(name, measurements_dir=tmp_path)
