"""Compile cache, loader checks, and the no-casadi guarantee of the filter path."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import types

import pytest

from leonav_runtime.core import compiled, key_memo

NO_CASADI_SCRIPT = r"""
import sys
sys.modules["casadi"] = None  # any `import casadi` now raises ImportError
import math
import numpy as np
from leonav_runtime.core import compiled, records, filter as lf
from leonav_runtime.gen import state_layout as L
lib = compiled.load()
p = np.zeros(L.NP)
p[L.P_LAT0_RAD], p[L.P_H0_M], p[L.P_VRW], p[L.P_ARW] = math.radians(45), 100.0, 1e-3, 1e-4
x = np.zeros(L.NX); x[L.X_Q_NB] = 1.0
u = lf.stationary_imu(x, 0.01, p, lib)
t = np.arange(1, 101) * 0.01
recs = records.merge_records(
    records.imu_records(t, np.tile(u[L.U_DTHETA_B_SLICE], (100, 1)), np.tile(u[L.U_DVEL_B_SLICE], (100, 1))),
    records.measurement_records([0.5, 1.0], L.MEAS_POS_E, [0.0, 0.0], 1.0))
res = lf.EKF(x, np.eye(L.NDX), p, library=lib).run(recs)
assert res.n_imu == 100 and res.n_applied == 2, (res.n_imu, res.n_applied)
assert not any(m == "casadi" or m.startswith("casadi.") for m, v in sys.modules.items() if v is not None)
print("ok")
"""


def test_filter_path_never_imports_casadi():
    proc = subprocess.run([sys.executable, "-c", NO_CASADI_SCRIPT], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "ok"


def test_second_load_uses_the_cache_and_same_library():
    first = compiled.load()
    compiled.clear_process_cache()
    again = compiled.build()
    assert again.compiled_objects == [] and not again.linked and again.compile_time_s == 0.0
    assert again.library == first.build.library and again.key == first.build.key
    assert compiled.load() is not first  # a fresh ctypes load of the cached file


def test_changed_source_or_flags_give_a_new_key(tmp_path):
    gen, csrc = tmp_path / "gen", tmp_path / "csrc"
    shutil.copytree(compiled.GEN_DIR, gen)
    shutil.copytree(compiled.CSRC_DIR, csrc)
    version = compiled.compiler_version(compiled.compiler())
    includes = [gen, csrc]
    driver = csrc / "leonav_driver.c"
    key = compiled.object_key(driver, includes, compiled.cflags(), version)
    assert key == compiled.object_key(compiled.CSRC_DIR / "leonav_driver.c",
                                      [compiled.GEN_DIR, compiled.CSRC_DIR], compiled.cflags(), version)
    driver.write_text(driver.read_text() + "\n/* changed */\n")
    assert compiled.object_key(driver, includes, compiled.cflags(), version) != key
    header = gen / "state_layout.h"  # a header change invalidates what includes it (the driver)...
    key = compiled.object_key(driver, includes, compiled.cflags(), version)
    gen_c = gen / "c" / "leonav_h_pos_e.c"
    gen_key = compiled.object_key(gen_c, includes, compiled.cflags(), version)
    header.write_text(header.read_text() + "\n")
    assert compiled.object_key(driver, includes, compiled.cflags(), version) != key
    # ... but not a generated function, which includes no project header
    assert compiled.object_key(gen_c, includes, compiled.cflags(), version) == gen_key
    other = gen / "c" / "leonav_h_pos_n.c"
    other.write_text(other.read_text() + "\n")
    assert compiled.object_key(gen_c, includes, compiled.cflags(), version) == gen_key
    gen_c.write_text(gen_c.read_text() + "\n")
    assert compiled.object_key(gen_c, includes, compiled.cflags(), version) != gen_key
    assert compiled.object_key(gen_c, includes, compiled.cflags() + ["-O3"], version) != \
        compiled.object_key(gen_c, includes, compiled.cflags(), version)
    assert compiled.object_key(gen_c, includes, compiled.cflags(), version + "x") != \
        compiled.object_key(gen_c, includes, compiled.cflags(), version)


def test_layout_mismatch_is_reported():
    lib = compiled.load()
    wrong = types.SimpleNamespace(**{k: getattr(lib.layout, k) for k in ("NX", "NDX", "NP", "NAUX", "NU",
                                                                         "MEAS_TABLE")})
    naux = wrong.NAUX
    wrong.NAUX += 1
    with pytest.raises(compiled.LayoutMismatchError,
                       match=rf"leonav_h_pseudorange: input 1 is {naux}x1, expected {naux + 1}x1"):
        compiled.check_layout(lib.lib, wrong)
    wrong.NAUX -= 1
    Observable = type(wrong.MEAS_TABLE[0])
    wrong.MEAS_TABLE = tuple(wrong.MEAS_TABLE) + (Observable(len(wrong.MEAS_TABLE), "future_sensor", 1, "FUTURE_SENSOR", "m"),)
    with pytest.raises(compiled.LayoutMismatchError, match="leonav_h_future_sensor: missing"):
        compiled.check_layout(lib.lib, wrong)


def test_missing_compiler_and_compile_errors_are_clear(monkeypatch, tmp_path):
    monkeypatch.setenv("CC", "/nonexistent/cc")
    with pytest.raises(compiled.CompilerError, match="no C compiler found"):
        compiled.build()
    monkeypatch.delenv("CC")
    gen, csrc = tmp_path / "gen", tmp_path / "csrc"
    (gen / "c").mkdir(parents=True)
    csrc.mkdir()
    (gen / "c" / "tiny_gen.c").write_text("int tiny(void) { return 1; }\n")
    (csrc / "broken.c").write_text("int broken(void) { return undeclared_name; }\n")
    with pytest.raises(compiled.CompilerError, match="undeclared_name"):
        compiled.build(gen, csrc, out_dir=tmp_path / "build")


def test_generated_tables_reach_the_driver():
    """The driver's observable table and code names come from the generated lists."""
    lib = compiled.load()
    L = lib.layout
    for m in L.MEAS_TABLE:
        assert lib.lib.leonav_meas_name(m.kind).decode() == m.name
        assert lib.lib.leonav_meas_unit(m.kind).decode() == m.unit
    assert lib.lib.leonav_meas_name(L.NMEAS) is None and lib.lib.leonav_meas_name(L.MEAS_IMU) is None
    for rc, name in L.RETURN_NAMES.items():
        assert lib.lib.leonav_code_name(rc).decode() == name == compiled.code_name(rc)
    assert lib.meas_ids == {m.suffix: m.kind for m in L.MEAS_TABLE}


# ---- the key memo (issue 25: a warm process no longer hashes the ~188 sources) ----------------

def _copy_sources(tmp_path):
    gen, csrc = tmp_path / "gen", tmp_path / "csrc"
    shutil.copytree(compiled.GEN_DIR, gen)
    shutil.copytree(compiled.CSRC_DIR, csrc)
    return gen, csrc, [gen, csrc], tmp_path / "build"


def _content_keys(gen, csrc, version):
    """The keys computed the plain way: every file read and hashed."""
    srcs, includes = compiled.sources(gen, csrc), [gen, csrc]
    return ([compiled.object_key(s, includes, compiled.cflags(), version) for s in srcs],
            compiled._sources_key(srcs, includes, compiled.cflags()))


def _memo_keys(gen, csrc, version, out):
    out.mkdir(exist_ok=True)
    return compiled.source_keys(compiled.sources(gen, csrc), [gen, csrc], compiled.cflags(), version, out)


def _memo_file(out):
    (memo,) = out.glob("keymemo-*.json")
    return memo


def _rewrite_same_size(path, old: bytes, new: bytes, before_ctime_ns: int):
    """Replace `old` by `new` (same length) in place and put the mtime back; rewritten until the
    ctime differs from `before_ctime_ns` (time stamps are coarse: one clock tick is a few ms)."""
    assert len(old) == len(new)
    st = path.stat()
    data = path.read_bytes()
    assert old in data
    for _ in range(100_000):
        with open(path, "r+b") as fh:
            fh.write(data.replace(old, new, 1))
        os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
        if path.stat().st_ctime_ns != before_ctime_ns:
            break
    after = path.stat()
    assert (after.st_size, after.st_mtime_ns, after.st_ino) == (st.st_size, st.st_mtime_ns, st.st_ino)
    assert after.st_ctime_ns != before_ctime_ns


def test_key_memo_gives_the_content_keys_and_a_warm_lookup_reads_no_file(tmp_path, monkeypatch):
    monkeypatch.setattr(key_memo, "RACY_NS", 0)
    gen, csrc, _, out = _copy_sources(tmp_path)
    version = compiled.compiler_version(compiled.compiler())
    plain = _content_keys(gen, csrc, version)
    assert _memo_keys(gen, csrc, version, out) == plain
    body = json.loads(_memo_file(out).read_text())
    assert body["object_keys"] == plain[0] and len(body["files"]) >= len(plain[0])

    def no_hashing(*args, **kwargs):
        raise AssertionError("hashed although the memo is valid")
    monkeypatch.setattr(compiled, "object_key", no_hashing)
    assert _memo_keys(gen, csrc, version, out) == plain
    # another compiler version or flag set is another memo, not this one's keys
    monkeypatch.undo()
    monkeypatch.setattr(key_memo, "RACY_NS", 0)
    assert _memo_keys(gen, csrc, version + "x", out)[0] == _content_keys(gen, csrc, version + "x")[0] != plain[0]
    assert len(list(out.glob("keymemo-*.json"))) == 2


def test_same_size_edit_with_the_mtime_put_back_is_rehashed(tmp_path, monkeypatch):
    monkeypatch.setattr(key_memo, "RACY_NS", 0)
    gen, csrc, _, out = _copy_sources(tmp_path)
    version = compiled.compiler_version(compiled.compiler())
    srcs = compiled.sources(gen, csrc)
    before = _memo_keys(gen, csrc, version, out)
    recorded = json.loads(_memo_file(out).read_text())["files"]
    gen_c = gen / "c" / "leonav_h_pos_e.c"
    i = srcs.index(gen_c)
    _rewrite_same_size(gen_c, b"leonav_h_pos_e", b"leonav_h_pos_f", recorded[str(gen_c)][4])
    after = _memo_keys(gen, csrc, version, out)
    assert after == _content_keys(gen, csrc, version)
    assert after[0][i] != before[0][i] and after[1] != before[1]
    assert [k for j, k in enumerate(after[0]) if j != i] == [k for j, k in enumerate(before[0]) if j != i]
    # a header the driver includes, edited the same way: the driver's key changes
    driver = srcs.index(csrc / "leonav_driver.c")
    recorded = json.loads(_memo_file(out).read_text())["files"]
    header = gen / "state_layout.h"
    text = header.read_bytes()
    word = next(w for w in (b"define", b"include", b"int") if w in text)
    _rewrite_same_size(header, word, word.upper(), recorded[str(header.resolve())][4])
    again = _memo_keys(gen, csrc, version, out)
    assert again == _content_keys(gen, csrc, version) and again[0][driver] != after[0][driver]


def test_added_shadowing_header_or_source_changes_the_keys(tmp_path, monkeypatch):
    monkeypatch.setattr(key_memo, "RACY_NS", 0)
    gen, csrc, _, out = _copy_sources(tmp_path)
    version = compiled.compiler_version(compiled.compiler())
    before = _memo_keys(gen, csrc, version, out)
    driver = compiled.sources(gen, csrc).index(csrc / "leonav_driver.c")
    # found beside the driver before gen/state_layout.h: a folder's stat, not a file's, shows it
    (csrc / "state_layout.h").write_text((gen / "state_layout.h").read_text() + "\n/* shadow */\n")
    after = _memo_keys(gen, csrc, version, out)
    assert after == _content_keys(gen, csrc, version) and after[0][driver] != before[0][driver]
    (gen / "c" / "zz_extra.c").write_text("int zz_extra(void) { return 2; }\n")
    more = _memo_keys(gen, csrc, version, out)
    assert more == _content_keys(gen, csrc, version) and len(more[0]) == len(after[0]) + 1


def test_corrupt_or_altered_memo_is_ignored_and_rewritten(tmp_path, monkeypatch):
    monkeypatch.setattr(key_memo, "RACY_NS", 0)
    gen, csrc, _, out = _copy_sources(tmp_path)
    version = compiled.compiler_version(compiled.compiler())
    plain = _content_keys(gen, csrc, version)
    _memo_keys(gen, csrc, version, out)
    memo = _memo_file(out)
    good = json.loads(memo.read_text())
    altered = dict(good, object_keys=["0" * 64] + good["object_keys"][1:])   # check no longer matches
    for bad in (b"", b"{not json", memo.read_bytes()[:200], json.dumps(altered).encode(),
                json.dumps(dict(good, format=99)).encode()):
        memo.write_bytes(bad)
        assert _memo_keys(gen, csrc, version, out) == plain
        assert json.loads(memo.read_text()) == good   # rewritten whole
    assert not list(out.glob("*.tmp"))


def test_files_changed_just_now_are_not_memoized(tmp_path, monkeypatch):
    gen, csrc, _, out = _copy_sources(tmp_path)   # every copy's ctime is now, within RACY_NS
    version = compiled.compiler_version(compiled.compiler())
    assert _memo_keys(gen, csrc, version, out) == _content_keys(gen, csrc, version)
    assert not list(out.glob("keymemo-*.json"))
    monkeypatch.setenv(compiled.MEMO_ENV, "off")
    monkeypatch.setattr(key_memo, "RACY_NS", 0)
    assert _memo_keys(gen, csrc, version, out) == _content_keys(gen, csrc, version)
    assert not list(out.glob("keymemo-*.json"))


MEMO_SCRIPT = r"""
import sys
from pathlib import Path
from leonav_runtime.core import compiled, key_memo
key_memo.RACY_NS = 0
gen, csrc, out = map(Path, sys.argv[1:4])
keys = compiled.source_keys(compiled.sources(gen, csrc), [gen, csrc], compiled.cflags(),
                            compiled.compiler_version(compiled.compiler()), out)
print(keys[1], ",".join(keys[0]))
"""


def test_processes_starting_at_once_agree_and_leave_a_valid_memo(tmp_path, monkeypatch):
    monkeypatch.setattr(key_memo, "RACY_NS", 0)
    gen, csrc, _, out = _copy_sources(tmp_path)
    out.mkdir()
    (out / "keymemo-0.json").write_text("{")   # an unrelated corrupt memo is left alone by readers
    version = compiled.compiler_version(compiled.compiler())
    plain = _content_keys(gen, csrc, version)
    procs = [subprocess.Popen([sys.executable, "-c", MEMO_SCRIPT, str(gen), str(csrc), str(out)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(4)]
    results = [p.communicate(timeout=300) for p in procs]
    assert all(p.returncode == 0 for p in procs), [r[1] for r in results]
    assert {r[0] for r in results} == {f"{plain[1]} {','.join(plain[0])}\n"}
    memo = next(p for p in out.glob("keymemo-*.json") if p.name != "keymemo-0.json")
    body = json.loads(memo.read_text())
    assert body["check"] == key_memo._memo_check(body) and body["object_keys"] == plain[0]
    assert not list(out.glob("*.tmp"))


def test_build_key_is_the_content_key_with_the_memo():
    info = compiled.build()
    version = compiled.compiler_version(compiled.compiler())
    keys = _content_keys(compiled.GEN_DIR, compiled.CSRC_DIR, version)[0]
    assert info.key == compiled.library_key(keys, list(compiled.LDFLAGS) + list(compiled.LIBS))
