"""Processes that start on an empty build cache at once compile the C once: one builds under the
cache's lock, the others wait and load its objects (xdist workers, parallel commands)."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

BUILD = """
import json, sys, time
from pathlib import Path
from leonav_runtime.core import compiled
start = time.time()
info = compiled.build(Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3]))
print(json.dumps({"compiled": info.compiled_objects, "linked": info.linked, "library": str(info.library)}))
"""


def test_two_processes_on_an_empty_cache_compile_each_object_once(tmp_path):
    if shutil.which("cc") is None:
        pytest.skip("needs the C compiler cc")
    gen, csrc, cache = tmp_path / "gen", tmp_path / "csrc", tmp_path / "cache"
    (gen / "c").mkdir(parents=True)
    csrc.mkdir()
    for k in range(6):  # enough work that the two processes overlap
        body = "\n".join(f"double f{k}_{j}(double x) {{ return x * {j}.5 + {k}; }}" for j in range(400))
        (gen / "c" / f"fn{k}.c").write_text(body + "\n")
    (csrc / "leonav_driver.c").write_text("int leonav_driver_version(void) { return 1; }\n")
    procs = [subprocess.Popen([sys.executable, "-c", BUILD, str(gen), str(csrc), str(cache)], cwd=REPO,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = []
    for p in procs:
        out, err = p.communicate(timeout=120)
        assert p.returncode == 0, err
        outs.append(json.loads(out.strip().splitlines()[-1]))
    compiled = sorted(name for o in outs for name in o["compiled"])
    assert compiled == sorted([f"fn{k}.c" for k in range(6)] + ["leonav_driver.c"])   # each object once
    assert sum(o["linked"] for o in outs) == 1 and outs[0]["library"] == outs[1]["library"]
    assert not list(cache.glob("*.tmp"))
