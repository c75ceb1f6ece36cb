"""The installed tree: `models/`, `codegen/` and `hardware/` install as `leonav.models`,
`leonav.codegen` and `leonav.hardware` (setup.py), so a user's own top-level `models` or
`hardware` package never collides with leonav's."""
from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def wheel_tree(tmp_path_factory) -> Path:
    """The project's wheel, built without network (the venv's setuptools) and unpacked."""
    if importlib.util.find_spec("setuptools") is None or importlib.util.find_spec("wheel") is None:
        pytest.skip("needs setuptools and wheel in this environment to build the wheel offline")
    out = tmp_path_factory.mktemp("wheel")
    # built from a copy of the tracked files: an in-tree build leaves build/ and *.egg-info behind
    listed = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, timeout=60)
    if listed.returncode != 0:
        pytest.skip("needs the git checkout to list the project's files")
    src = out / "src"
    for rel in filter(None, listed.stdout.decode().split("\0")):
        if (ROOT / rel).is_file():
            (src / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / rel, src / rel)
    proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                           "-w", str(out), str(src)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    (whl,) = out.glob("leonav-*.whl")
    tree = out / "tree"
    zipfile.ZipFile(whl).extractall(tree)
    return tree


def _python(code: str, tree: Path, cwd: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"} | {"PYTHONPATH": str(tree)}
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=120)


def test_wheel_has_no_top_level_models_codegen_or_hardware(wheel_tree):
    top = {p.name for p in wheel_tree.iterdir() if not p.name.endswith(".dist-info")}
    assert top == {"leonav", "leonav_runtime"}, top
    for name in ("models", "codegen", "hardware"):
        assert (wheel_tree / "leonav" / name / "__init__.py").is_file(), name
    assert (wheel_tree / "leonav" / "hardware" / "pi" / "Makefile").is_file()   # package data came along
    assert (wheel_tree / "leonav_runtime" / "gen" / "state_layout.py").is_file()


@pytest.mark.parametrize("name", ["models", "codegen", "hardware"])
def test_installed_tree_has_no_top_level_import_name(wheel_tree, tmp_path, name):
    proc = _python(f"import {name}", wheel_tree, tmp_path)
    assert proc.returncode == 1 and "ModuleNotFoundError" in proc.stderr, proc.stderr
    proc = _python(f"import leonav.{name}; print(leonav.{name}.__file__)", wheel_tree, tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert Path(proc.stdout.strip()).is_relative_to(wheel_tree / "leonav" / name)


def test_a_folder_imported_under_its_bare_name_says_how_to_import_it():
    """From the repository root the folders are on sys.path; the guard in each __init__ refuses the
    bare name (two names for one module would mean two copies of its state)."""
    proc = subprocess.run([sys.executable, "-c", "import models"], cwd=ROOT, capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 1 and "ModuleNotFoundError" in proc.stderr and "leonav.models" in proc.stderr
