"""The runtime and the device code reach the models only through the generated code.

`leonav_runtime/` and `hardware/` must not import `casadi`, `models` or `codegen`: every
equation they use is generated into `leonav_runtime/gen/` (ARCHITECTURE.md, "Data flows
one way"). The only exceptions are the commands whose job is symbolic (regenerating the
code, symbolic observability): they import `codegen` inside the command function, so the
rest of the CLI never loads casadi.
"""
from __future__ import annotations

import ast
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FORBIDDEN = ("casadi", "leonav.models", "leonav.codegen")
# command modules whose *function bodies* may import codegen (the symbolic tools)
SYMBOLIC_COMMANDS = {"leonav_runtime/commands/codegen.py", "leonav_runtime/commands/observability.py"}


def _imports(tree: ast.AST, top_level_only: bool):
    """(line, module) of every import; with top_level_only, those outside function bodies."""
    skip: set[int] = set()
    if top_level_only:
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                skip.update(id(n) for n in ast.walk(node) if n is not node)
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            for a in node.names:
                yield node.lineno, a.name
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.lineno, node.module


def _runtime_files():
    for pkg in ("leonav_runtime", "hardware"):
        for path in sorted((ROOT / pkg).rglob("*.py")):
            yield path.relative_to(ROOT).as_posix(), path


def test_runtime_and_hardware_never_import_models_or_casadi():
    offenders = []
    for rel, path in _runtime_files():
        tree = ast.parse(path.read_text(), filename=rel)
        for line, module in _imports(tree, top_level_only=rel in SYMBOLIC_COMMANDS):
            if any(module == f or module.startswith(f + ".") for f in FORBIDDEN):
                offenders.append(f"{rel}:{line} imports {module}")
    assert not offenders, "the runtime must reach models only through gen/:\n" + "\n".join(offenders)


def test_the_check_finds_a_forbidden_import():
    """The walker itself: a nested and a top-level import are both found."""
    tree = ast.parse("import numpy\ndef f():\n    from leonav.models.state import NX\n")
    assert [m for _, m in _imports(tree, top_level_only=False)] == ["numpy", "leonav.models.state"]
    assert [m for _, m in _imports(tree, top_level_only=True)] == ["numpy"]


_BLOCKER = textwrap.dedent("""
    import importlib.abc, sys
    class _Block(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] == "casadi" or name == "leonav.models" or name.startswith("leonav.models."):
                raise ImportError(f"{name} is blocked: the run path must not need it")
            return None
    sys.meta_path.insert(0, _Block())
    from leonav_runtime.cli import main
    rc = main(sys.argv[1:])
    assert "casadi" not in sys.modules and "leonav.models" not in sys.modules
    sys.exit(rc)
""")


def _run_blocked(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    return subprocess.run([sys.executable, "-c", _BLOCKER, *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600)


@pytest.mark.slow
def test_beacons_and_replay_run_with_casadi_unimportable(tmp_path):
    """`leonav beacons --simulate` and `leonav session synth` + `leonav replay` end to end
    with casadi and models made unimportable."""
    tle = ROOT.parent / "shared" / "data" / "tle" / "starlink_2026-02-23.txt"
    if not tle.exists():
        pytest.skip(f"needs {tle} (../shared/data)")
    r = _run_blocked(["beacons", str(tmp_path / "sim.cu8"), "--simulate", "--tle", str(tle), "--duration", "4.5",
                      "--sim-rate", "1e6", "--band", "1e6", "--n-sats", "2", "--tones", "3", "--cn0", "40",
                      "--start", "2026-02-23T06:00:00Z", "--out", str(tmp_path / "beacons")], tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    assert (tmp_path / "beacons" / "doppler_rate_measurements.csv").exists()
    r = _run_blocked(["session", "synth", str(tmp_path / "s"), "--seconds", "5", "--sdr-rate", "200e3"], tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    r = _run_blocked(["replay", str(tmp_path / "s"), "--out", str(tmp_path / "o")], tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    assert (tmp_path / "o" / "metrics.json").exists()


def test_building_the_command_line_loads_no_heavy_library():
    """Every command registers itself without importing scipy, matplotlib or casadi (they
    cost 0.2-0.5 s of start-up each; `leonav spp` is timed against rnx2rtkp as a command)."""
    code = ("import sys\nfrom leonav_runtime.cli import build_parser\nbuild_parser()\n"
            "print(sorted({m.split('.')[0] for m in sys.modules} & {'scipy', 'matplotlib', 'casadi', 'pandas'}))")
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]", proc.stdout
