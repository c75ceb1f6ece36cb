"""The `leonav` command line runs NumPy's BLAS on one thread unless the environment names a
number (its matrices are small; extra OpenBLAS threads only cost CPU at start and while idle)."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

PROBE = ("import json, leonav_runtime.cli, numpy; from threadpoolctl import threadpool_info; "
         "print(json.dumps([p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas']))")


def _blas_threads(**env: str) -> list[int]:
    from leonav_runtime.cli import BLAS_THREAD_VARIABLES

    clean = {k: v for k, v in os.environ.items() if k not in BLAS_THREAD_VARIABLES}
    r = subprocess.run([sys.executable, "-c", PROBE], env={**clean, **env}, capture_output=True, text=True,
                       timeout=60, check=True)
    return json.loads(r.stdout)


def test_one_blas_thread_by_default_and_the_users_number_when_given():
    default = _blas_threads()
    if not default:
        pytest.skip("NumPy reports no BLAS thread pool here")
    assert set(default) == {1}
    assert set(_blas_threads(OPENBLAS_NUM_THREADS="2")) == {2}
