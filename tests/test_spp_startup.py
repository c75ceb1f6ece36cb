"""`leonav spp` imports only what it needs (issue 25): the command line builds the parser of the
one command it names, and the solution path loads no heavy library, no other command, no
scenario/simulation/filter code (the GNSS-only EKF only with --ekf). Checked in a fresh
interpreter after a real run on the shared GEONET file (sys.modules at the end)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from tests.conftest import modules_after_main, shared_file

ROOT = Path(__file__).resolve().parents[1]
HEAVY = {"casadi", "scipy", "matplotlib", "pandas", "sgp4", "pyproj", "astropy", "tqdm", "sigmf", "pymavlink",
         "serial", "pynmea2", "hatanaka", "ncompress", "multiprocessing", "tomllib", "tomli"}
NOT_FOR_SPP = ("leonav_runtime.commands.", "leonav_runtime.scenarios", "leonav_runtime.simulation",
               "leonav_runtime.sweep", "leonav_runtime.inputs", "leonav_runtime.beacons", "leonav_runtime.sky",
               "leonav_runtime.core.filter", "leonav_runtime.gnss.gnss_ekf", "leonav.codegen")


def _unexpected(modules: set[str]) -> list[str]:
    tops = {m.split(".")[0] for m in modules}
    return sorted((tops & HEAVY) | {m for m in modules if m.startswith(NOT_FOR_SPP) and m != "leonav_runtime.commands.spp"})


def test_spp_imports_only_what_it_needs(tmp_path):
    o, n = shared_file("gnss_rinex/07590920.05o"), shared_file("gnss_rinex/07590920.05n")
    rc, modules = modules_after_main(["spp", str(o), "--nav", str(n), "--out", str(tmp_path / "out")], tmp_path)
    assert rc == 0 and (tmp_path / "out" / "07590920_05o.pos").is_file()
    assert {"leonav_runtime.commands.spp", "leonav_runtime.gnss.spp", "leonav_runtime.gnss.rinex_obs",
            "leonav_runtime.core.navfuncs"} <= modules   # the run did go through the solution
    assert _unexpected(modules) == []


def test_spp_ekf_loads_the_filter_only_when_asked(tmp_path):
    o, n = shared_file("gnss_rinex/07590920.05o"), shared_file("gnss_rinex/07590920.05n")
    rc, modules = modules_after_main(["spp", str(o), "--nav", str(n), "--ekf", "--out", str(tmp_path / "out")], tmp_path)
    assert rc == 0 and (tmp_path / "out" / "07590920_05o_ekf.pos").is_file()
    assert "leonav_runtime.gnss.gnss_ekf" in modules
    assert sorted({m.split(".")[0] for m in modules} & HEAVY - {"multiprocessing", "tomllib"}) == []


def test_compressed_input_loads_its_decompressor_only_then(tmp_path):
    import gzip

    o, n = shared_file("gnss_rinex/07590920.05o"), shared_file("gnss_rinex/07590920.05n")
    crx = tmp_path / "07590920.05d.gz"
    hatanaka = __import__("pytest").importorskip("hatanaka", reason="hatanaka (a leonav dependency) not installed")
    crx.write_bytes(gzip.compress(hatanaka.rnx2crx(o.read_bytes())))
    rc, modules = modules_after_main(["spp", str(crx), "--nav", str(n), "--out", str(tmp_path / "out")], tmp_path)
    assert rc == 0 and "hatanaka" in modules
    assert _unexpected(modules - {m for m in modules if m.split(".")[0] in ("hatanaka", "ncompress")}) == []


def test_other_command_words_still_get_the_full_parser(tmp_path):
    """A mistyped command lists every command; `completion` describes all of them."""
    code = ("import sys\nfrom leonav_runtime.cli import build_parser\n"
            "p = build_parser('completion')\nsub = next(a for a in p._actions if a.dest == 'command')\n"
            "print(len(sub.choices), 'spp' in sub.choices, 'sweep' in sub.choices)\n"
            "p = build_parser('spp')\nsub = next(a for a in p._actions if a.dest == 'command')\n"
            "print(sorted(sub.choices))")
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.returncode == 0, proc.stderr
    full, lean = proc.stdout.strip().splitlines()
    count, has_spp, has_sweep = full.split()
    assert int(count) > 10 and has_spp == has_sweep == "True"
    assert lean == "['spp']"
    proc = subprocess.run([sys.executable, "-m", "leonav_runtime.cli", "sppp"], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.returncode == 2 and "invalid choice: 'sppp'" in proc.stderr and "sweep" in proc.stderr
