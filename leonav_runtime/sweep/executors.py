"""Where Monte Carlo trials run: any `concurrent.futures.Executor`.

`make_executor(workers=N)` gives a local process pool (the default); `dask_address` gives
the executor of a Dask distributed client connected to that scheduler, so the same sweep
runs on a cluster. Trials carry their own seeds (derived from the scenario seed and the
trial index), so results do not depend on which executor ran them or in what order.

Local work runs with one BLAS thread per process: a sweep's matrices are small (up to a few
hundred rows, the base station's orbit fit), so N workers each with N BLAS threads on N cores
spin against each other. passive-phase-base: 44 s of CPU per trial in a 2-worker sweep, 15 s
with one BLAS thread; and inline and pooled trials then sum in the same order.
"""
from __future__ import annotations

import contextlib
import os
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from typing import Any, Callable, Iterator, Sequence

from threadpoolctl import threadpool_limits

from leonav_runtime.common.errors import UserInputError


def add_executor_arguments(parser) -> None:
    """--workers, --dask and --no-progress of the commands that run Monte Carlo work."""
    parser.add_argument("--workers", type=int, default=None, metavar="N",
                        help="local worker processes (default: all cores; 1 runs in this process)")
    parser.add_argument("--dask", default=None, metavar="ADDRESS",
                        help="run the trials on a Dask distributed scheduler, e.g. tcp://127.0.0.1:8786")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


class _InlineExecutor(Executor):
    """Runs each task at submission, in this process (workers=1: no pickling, easy debugging)."""

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        future: Future = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # surfaced by future.result(), like a real executor
            future.set_exception(exc)
        return future


@contextlib.contextmanager
def make_executor(workers: int | None = None, dask_address: str | None = None,
                  connect_timeout_s: float = 10.0) -> Iterator[Executor]:
    """Context manager yielding the executor for a sweep.

    workers: local processes (default: all cores; 1 runs inline). dask_address: a Dask
    scheduler address such as ``tcp://127.0.0.1:8786``; the `distributed` package is then
    required (the project's extra, ``pip install '.[dask]'`` from a checkout, or
    ``pip install 'dask[distributed]'``).
    """
    if dask_address:
        try:
            from distributed import Client
        except ImportError:
            raise UserInputError(
                "--dask needs the 'distributed' package: pip install '.[dask]' (leonav's [dask] extra, "
                "from a source checkout) or pip install 'dask[distributed]'"
            ) from None
        try:
            client = Client(dask_address, timeout=f"{connect_timeout_s}s")
        except (OSError, TimeoutError) as exc:
            raise UserInputError(f"--dask {dask_address}: cannot reach the scheduler ({exc})") from None
        try:
            yield client.get_executor()
        finally:
            client.close()
        return
    n = workers or os.cpu_count() or 1
    if n < 1:
        raise UserInputError(f"--workers {workers}: expected an integer >= 1")
    if n == 1:
        with threadpool_limits(1, user_api="blas"):
            yield _InlineExecutor()
        return
    with ProcessPoolExecutor(max_workers=n, initializer=_one_blas_thread) as pool:
        yield pool


def _one_blas_thread() -> None:
    threadpool_limits(1, user_api="blas")   # kept for the worker's life (module doc)


def map_in_order(executor: Executor, fn: Callable[[Any], Any], tasks: Sequence[Any],
                 on_done: Callable[[], None] | None = None) -> list[Any]:
    """Run `fn(task)` for every task on `executor`; results in task order.

    `on_done` is called once per finished task (for a progress bar), in completion order.
    """
    futures = [executor.submit(fn, task) for task in tasks]
    if on_done is not None:
        for _ in as_completed(futures):
            on_done()
    return [f.result() for f in futures]

