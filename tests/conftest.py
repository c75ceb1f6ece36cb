"""Shared test fixtures.

`shared_data` points at ../shared/data (real public fixtures, read in place, never
copied). Tests that need it skip with a clear reason when it is absent.
"""
from __future__ import annotations

import contextlib
import hashlib
import http.server
import os
import shutil
import subprocess
import tempfile
import threading
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("LEONAV_SHARED_DATA", REPO_ROOT.parent / "shared" / "data"))


def shared_file(relative: str) -> Path:
    """Path of a file under ../shared/data; skips the calling test if it is missing."""
    path = SHARED_DATA / relative
    if not path.exists():
        pytest.skip(f"needs ../shared/data/{relative} (real public fixture, see SOURCES.md); not found at {path}")
    return path


@pytest.fixture
def shared_data() -> Path:
    """The ../shared/data folder; skips when absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"needs ../shared/data (real public fixtures); not found at {SHARED_DATA}")
    return SHARED_DATA


def pytest_collection_modifyitems(config, items) -> None:
    """Tests marked slow (the longest, 10-40 s each: paced live runs, subprocess pipelines) run
    first, so the workers start them at once instead of one of them trailing at the end of the
    run; the order of the others is kept."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)


def pytest_xdist_auto_num_workers(config) -> int:
    """Workers for `pytest -n auto`: two per core (at most 8). About a third of the suite's
    wall time is waiting (live navigation paced at the recorded rate, subprocesses, serial
    ptys), so a second worker per core fills it; more only costs memory."""
    return min(8, 2 * (os.cpu_count() or 1))


PI_DIR = REPO_ROOT / "hardware" / "pi"


def pi_program(cc: str = "cc") -> Path:
    """hardware/pi's standalone program built by its Makefile with `cc`, once per source content:
    the build (about 10 s for the generated C) is shared by the tests and xdist workers that
    need it, under a lock, in a temporary folder named by the hash of every source it reads."""
    if shutil.which("make") is None or shutil.which(cc) is None:
        pytest.skip(f"needs make and the C compiler {cc}")
    sources = sorted([*PI_DIR.glob("Makefile"), *PI_DIR.glob("*.c"), *(REPO_ROOT / "leonav_runtime" / "gen").glob("*.[ch]"),
                      *(REPO_ROOT / "leonav_runtime" / "gen" / "c").glob("*.[ch]"),
                      *(REPO_ROOT / "leonav_runtime" / "csrc").glob("*.[ch]")])
    version = subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=30).stdout
    digest = hashlib.sha256(cc.encode() + version.encode())
    for src in sources:
        digest.update(src.name.encode() + src.read_bytes())
    out = Path(tempfile.gettempdir()) / f"leonav-test-pi-{digest.hexdigest()[:16]}"
    out.mkdir(exist_ok=True)
    from leonav_runtime.core.build_cache import build_lock

    with build_lock(out):   # the runtime's build-cache lock: one builder, the others wait
        if not (out / "leonav_filter").is_file():
            run = subprocess.run(["make", "-s", f"-j{os.cpu_count() or 1}", "-C", str(PI_DIR), f"CC={cc}", f"OUT={out}"],
                                 capture_output=True, text=True, timeout=300)
            assert run.returncode == 0, run.stderr
    return out / "leonav_filter"


def modules_after_main(argv: list[str], cwd: Path, timeout_s: float = 300.0) -> tuple[int, set[str]]:
    """Run `leonav argv` in a fresh interpreter (this checkout first on the path): its return code
    and every module it had imported at the end (sys.modules)."""
    import json
    import sys

    code = ("import json, sys\nfrom leonav_runtime.cli import main\nrc = main(json.loads(sys.argv[1]))\n"
            "print(json.dumps([rc, sorted(sys.modules)]))")
    proc = subprocess.run([sys.executable, "-c", code, json.dumps(argv)], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout_s, env=dict(os.environ, PYTHONPATH=str(REPO_ROOT)))
    assert proc.returncode == 0, proc.stderr[-2000:]
    rc, modules = json.loads(proc.stdout.strip().splitlines()[-1])
    return rc, set(modules)


def short_paper_scenario(duration_s: float, counts: list[int], source: str,
                         modes: tuple[str, ...] = ("gps+imu", "leo-alpha+imu"), **sections):
    """The paper scenario shortened to `duration_s` with the given Starlink counts and modes
    (and whole sections replaced by `sections`), validated like a scenario file."""
    import copy

    from leonav_runtime.scenarios.load import load_scenario, scenario_from_dict

    raw = copy.deepcopy(load_scenario("paper").raw)
    raw["time"]["duration_s"] = duration_s
    raw["starlink"]["counts"] = list(counts)
    raw["monte_carlo"]["modes"] = list(modes)
    raw.update(copy.deepcopy(sections))
    return scenario_from_dict(raw, source=source)


def orbit_phase_stream(duration_s: float, count: int, mode: str = "leo-phase+alpha+imu"):
    """(setup, nav, records, x_lin) of the paper scenario shortened to `duration_s` with Starlink
    at 10 Hz, `count` satellites and a 10 m position prior: the noise-free stream of `mode` on
    the truth, linearised where each record acts (`orbit_bound.records_on_truth`)."""
    from leonav_runtime.scenarios.load import load_scenario
    from leonav_runtime.sweep import montecarlo as mc
    from leonav_runtime.sweep import orbit_bound as ob

    paper = load_scenario("paper").raw
    scn = short_paper_scenario(duration_s, [count], f"<{mode}, {duration_s:g} s, {count} satellites>", modes=(mode,),
                               starlink={**paper["starlink"], "rate_hz": 10.0},
                               filter={**paper["filter"], "initial_position_sigma_m": 10.0})
    setup, nav = mc.setup_for(scn)
    recs, x_lin = ob.records_on_truth(setup, nav, mode, count)
    return setup, nav, recs, x_lin


@contextlib.contextmanager
def local_http_server(handler: type):
    """An HTTP server on 127.0.0.1 (a free port) answering with `handler` in a thread;
    yields its base URL 'http://127.0.0.1:PORT' and shuts it down after."""
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    server.daemon_threads = True
    thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=5)
