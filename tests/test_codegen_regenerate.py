"""The committed leonav_runtime/gen/ is exactly what the models generate today."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
from leonav.codegen.generate import (
    default_output_dir,
    diff_against,
    existing_files,
    generated_files,
)

REPO_ROOT = Path(__file__).resolve().parents[1]


def test_committed_generated_code_is_up_to_date():
    changed = diff_against(default_output_dir())
    assert not changed, (
        f"leonav_runtime/gen/ is stale ({', '.join(changed)} differ from a fresh generation): "
        "run `python -m leonav.codegen` (or `leonav codegen`) and commit the result"
    )


@pytest.mark.slow
def test_check_flag_fails_on_a_diff(tmp_path):
    out = tmp_path / "gen"
    run = lambda *a: subprocess.run([sys.executable, "-m", "leonav.codegen", *a], cwd=REPO_ROOT,  # noqa: E731
                                    capture_output=True, text=True)
    assert run("--out", str(out)).returncode == 0
    assert sorted(existing_files(out)) == sorted(generated_files())
    # one edited file, and a file of a function that is no longer generated (stale too): --check
    # names both and nothing else; regeneration rewrites the one and removes the other; then
    # --check passes (each run regenerates everything in memory: four runs, not six)
    c_file = out / "c" / "leonav_h_doppler.c"
    c_file.write_text(c_file.read_text().replace("casadi_real", "double", 1))
    (out / "c" / "leonav_h_removed.c").write_text("int leonav_h_removed;\n")
    result = run("--out", str(out), "--check")
    assert result.returncode == 1
    assert "c/leonav_h_doppler.c" in result.stderr and "python -m leonav.codegen" in result.stderr
    assert "c/leonav_h_removed.c" in result.stderr
    assert "leonav_h_pos_e" not in result.stderr
    regenerated = run("--out", str(out))
    assert regenerated.returncode == 0 and "removed: c/leonav_h_removed.c" in regenerated.stdout
    assert "changed: c/leonav_h_doppler.c" in regenerated.stdout and "leonav_h_pos_e.c" not in regenerated.stdout
    assert not (out / "c" / "leonav_h_removed.c").exists()
    assert run("--out", str(out), "--check").returncode == 0


@pytest.mark.slow
def test_a_model_change_rewrites_only_the_functions_it_reaches(monkeypatch):
    """One file per generated function: changing one observable's h changes that observable's
    h, innovation and orbit Jacobian (and the manifest), nothing else; its update (glue over
    the innovation and the shared Joseph step) and its information add call them as externals
    and stay as they were."""
    import dataclasses

    from leonav.models import state as S

    before = generated_files()
    changed_doppler = tuple(dataclasses.replace(m, h=lambda x, aux, p, h=m.h: 2.0 * h(x, aux, p))
                            if m.suffix == "doppler" else m for m in S.MEASUREMENTS)
    monkeypatch.setattr(S, "MEASUREMENTS", changed_doppler)
    after = generated_files()
    changed = {rel for rel in before if before[rel] != after.get(rel)}
    functions = {rel.removeprefix("c/").rsplit(".", 1)[0] for rel in changed if rel.startswith("c/")}
    assert functions == {"leonav_h_doppler", "leonav_innovation_doppler", "leonav_orbit_jac_doppler"}, functions
    assert changed - {rel for rel in changed if rel.startswith("c/")} == {"leonav_gen.json"}


def test_generated_files_are_small_and_hashed_in_the_manifest():
    """No generated C file over 5,000 lines (reviewable); the manifest's hash and line count of
    every function are those of its files."""
    import hashlib
    import json

    gen = default_output_dir()
    manifest = json.loads((gen / "leonav_gen.json").read_text())
    assert {f["file"] for f in manifest["functions"]} == {p.relative_to(gen).as_posix() for p in (gen / "c").glob("*.c")}
    for entry in manifest["functions"]:
        c_text = (gen / entry["file"]).read_text()
        h_text = (gen / entry["file"]).with_suffix(".h").read_text()
        assert hashlib.sha256((c_text + h_text).encode()).hexdigest() == entry["sha256"], entry["name"]
        assert c_text.count("\n") == entry["lines"] <= 5000, (entry["name"], entry["lines"])
    calls = {f["name"]: f["calls"] for f in manifest["functions"]}
    stages = calls["leonav_predict"]   # the predict is glue over its stages (some generated in parts)
    assert stages[0].startswith("leonav_predict_") and all(s.startswith("leonav_predict_") for s in stages)
    assert {"leonav_predict_transition", "leonav_predict_project"} <= set(stages) and len(stages) >= 3
    assert calls["leonav_update_doppler"] == ["leonav_innovation_doppler", "leonav_joseph"] and calls["leonav_pcrb_info_doppler"] == ["leonav_h_doppler"]


def test_layout_twin_matches_header():
    """state_layout.py and state_layout.h carry the same names and values; the twin has no casadi."""
    gen = default_output_dir()
    header = {}
    for line in (gen / "state_layout.h").read_text().splitlines():
        if line.startswith("#define LEONAV_") and len(line.split()) >= 3 and "(" not in line.split()[1]:
            _, name, value = line.split()[:3]
            header[name.removeprefix("LEONAV_")] = int(value.strip("()"))
    source = (gen / "state_layout.py").read_text()
    assert "import casadi" not in source and "from casadi" not in source
    namespace: dict = {}
    exec(compile(source, "state_layout.py", "exec"), namespace)
    twin = {k: v for k, v in namespace.items() if k.isupper() and isinstance(v, int)}
    assert header == twin
    from leonav.models import state as S

    assert (twin["NX"], twin["NDX"], twin["NP"], twin["NAUX"], twin["NU"], twin["NMEAS"]) == \
        (S.NX, S.NDX, S.NP, S.NAUX, S.NU, S.NMEAS)
    assert all(twin[f"MEAS_{m.name}"] == m.kind for m in namespace["MEAS_TABLE"])
    assert twin["NNAV"] == 9 and namespace["DX_NAV9_SLICE"] == slice(0, twin["NNAV"])
    # the observable table: C X-macro rows == Python MEAS_TABLE rows (kind, suffix, dim, name, unit)
    text = (gen / "state_layout.h").read_text()
    rows = re.findall(r'X\(LEONAV_MEAS_(\w+), (\w+), (\d+), "(\w+)", "([^"]*)"\)', text)
    assert [(twin[f"MEAS_{n}"], s, int(d), name, u) for n, s, d, name, u in rows] == \
        [tuple(m) for m in namespace["MEAS_TABLE"]]
    assert [m.kind for m in namespace["MEAS_TABLE"]] == list(range(twin["NMEAS"]))
    # driver codes: one success value, errors negative and disjoint from the other outcomes
    ret = {k: twin[k] for k in ("OK", "GATED", "FAILED")}
    errs = {k: v for k, v in twin.items() if k.startswith("ERR_")}
    assert ret == {"OK": 0, "GATED": 1, "FAILED": 2} and len(errs) == 5
    assert all(v < 0 for v in errs.values()) and len(set(errs.values())) == len(errs)
    assert namespace["RETURN_NAMES"] == {v: f"LEONAV_{k}" for k, v in {**ret, **errs}.items()}
    assert [twin[f"STATUS_{k}"] for k in ("IMU", "APPLIED", "GATED", "FAILED")] == [-1, 0, 1, 2]
    assert twin["X_Q_NB"] == S.X["q_nb"].offset and twin["DX_DTHETA"] == S.DX["dtheta"].offset
    assert twin["P_F_C_HZ"] == S.P["f_c_hz"].offset and twin["AUX_F_B"] == S.AUX["f_b"].offset
