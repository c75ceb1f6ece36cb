"""Executors: the same seeded tasks give identical results inline, in a process pool and on Dask."""
from __future__ import annotations

import numpy as np
import pytest

from leonav_runtime.common.errors import UserInputError
from leonav_runtime.sweep.executors import make_executor, map_in_order


def _seeded_task(task):
    seed, index = task
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(index + 1)[index])
    return rng.standard_normal(4).sum()


TASKS = [(11, i) for i in range(6)]


def test_inline_and_process_pool_agree():
    with make_executor(workers=1) as ex:
        inline = map_in_order(ex, _seeded_task, TASKS)
    done = []
    with make_executor(workers=2) as ex:
        pooled = map_in_order(ex, _seeded_task, TASKS, on_done=lambda: done.append(1))
    assert inline == pooled
    assert len(done) == len(TASKS)
    assert len(set(inline)) == len(TASKS)  # distinct streams per trial


def test_dask_local_cluster_on_loopback_agrees():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(host="127.0.0.1", n_workers=1, threads_per_worker=1,
                                  processes=False, protocol="tcp://", dashboard_address=None) as cluster:
        with make_executor(dask_address=cluster.scheduler_address) as ex:
            on_dask = map_in_order(ex, _seeded_task, TASKS)
    with make_executor(workers=1) as ex:
        assert on_dask == map_in_order(ex, _seeded_task, TASKS)


def test_unreachable_dask_scheduler_is_a_clear_error():
    pytest.importorskip("distributed")
    with pytest.raises(UserInputError, match="cannot reach the scheduler"):
        with make_executor(dask_address="tcp://127.0.0.1:9", connect_timeout_s=1.0):
            pass


def test_missing_dask_names_the_project_extra_and_the_plain_package(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    with pytest.raises(UserInputError) as info:
        with make_executor(dask_address="tcp://127.0.0.1:9"):
            pass
    assert "pip install '.[dask]'" in str(info.value) and "pip install 'dask[distributed]'" in str(info.value)
