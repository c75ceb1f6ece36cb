"""The committed leonav_runtime/gen/ is exactly what the models generate today."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from leonav.codegen.generate import FILES, default_output_dir, diff_against
REPO_ROOT = Path(__file__).resolve().parents[1]


def test_committed_generated_code_is_up_to_date():
    changed = diff_against(default_output_dir())
    assert not changed, (
        f"leonav_runtime/gen/ is stale ({', '.join(changed)} differ from a fresh generation): "
        "run `python -m leonav.codegen` (or `leonav codegen`) and commit the result"
    )


def test_check_flag_fails_on_a_diff(tmp_path):
    out = tmp_path / "gen"
    run = lambda *a: subprocess.run([sys.executable, "-m", "leonav.codegen", *a], cwd=REPO_ROOT,  # noqa: E731
                                    capture_output=True, text=True)
    assert run("--out", str(out)).returncode == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(FILES)
    assert run("--out", str(out), "--check").returncode == 0
    c_file = out / "leonav_gen.c"
    c_file.write_text(c_file.read_text().replace("casadi_real", "double", 1))
    result = run("--out", str(out), "--check")
    assert result.returncode == 1
    assert "leonav_gen.c" in result.stderr and "python -m leonav.codegen" in result.stderr


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
    assert (twin["NX"], twin["NDX"], twin["NP"], twin["NAUX"], twin["NU"], twin["NMEAS"]) == (21, 20, 14, 36, 6, 17)
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
    assert twin["X_Q_NB"] == 6 and twin["DX_DTHETA"] == 6 and twin["P_F_C_HZ"] == 10 and twin["AUX_F_B"] == 18
