"""Build time of the generated filter: a cold build against the rebuild after a one-observable
model change, measured side by side in one run (one object per generated function, so the
rebuild compiles the changed functions and links).

    python benchmarks/bench_rebuild.py

The model change is made in memory (the Doppler model doubled) and generated into a temporary
copy of leonav_runtime/gen/; the repository is not touched.
"""
from __future__ import annotations

import dataclasses
import shutil
import tempfile
import time
from pathlib import Path


def main() -> int:
    from leonav.codegen.generate import default_output_dir, generated_files
    from leonav.models import state as S
    from leonav_runtime.core import compiled

    with tempfile.TemporaryDirectory(prefix="leonav-rebuild-") as tmp:
        gen, cache = Path(tmp) / "gen", Path(tmp) / "cache"
        shutil.copytree(default_output_dir(), gen)
        t0 = time.perf_counter()
        cold = compiled.build(gen, compiled.CSRC_DIR, out_dir=cache)
        cold_s = time.perf_counter() - t0
        changed = tuple(dataclasses.replace(m, h=lambda x, aux, p, h=m.h: 2.0 * h(x, aux, p))
                        if m.suffix == "doppler" else m for m in S.MEASUREMENTS)
        original, S.MEASUREMENTS = S.MEASUREMENTS, changed
        try:
            files = generated_files()
        finally:
            S.MEASUREMENTS = original
        rewritten = [rel for rel, text in files.items() if (gen / rel).read_text() != text]
        for rel in rewritten:
            (gen / rel).write_text(files[rel])
        t0 = time.perf_counter()
        warm = compiled.build(gen, compiled.CSRC_DIR, out_dir=cache)
        warm_s = time.perf_counter() - t0
    n = len(cold.compiled_objects)
    print(f"cold build: {n} objects compiled and linked in {cold_s:.1f} s ({cold.compiler_version}, "
          f"{' '.join(cold.cflags)})")
    print(f"after a change of the Doppler model: {len(rewritten)} generated files rewritten, "
          f"{len(warm.compiled_objects)} objects recompiled ({', '.join(warm.compiled_objects)}), "
          f"rebuild {warm_s:.2f} s = {warm_s / cold_s:.2f} of the cold build")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
