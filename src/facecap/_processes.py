"""Independent pieces of work spread over worker processes (one home for how the package starts and feeds them)."""

from __future__ import annotations

import multiprocessing
import os
import warnings
from concurrent.futures import Future, ProcessPoolExecutor
from contextlib import contextmanager
from typing import Any, Callable, Iterator, Sequence

from tqdm.auto import tqdm

from ._threads import available_cores

__all__ = ["ProcessMap", "process_map"]

_ONE_THREAD = {"MKL_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


def _one_thread_each() -> None:
    """Worker start: one thread for every library, so that the workers share the cores instead of
    each spreading MKL's, OpenBLAS's and OpenCV's pools over all of them (set before any of them loads;
    MKL told again directly, for the worker's own thread, which runs every task)."""
    os.environ.update(_ONE_THREAD)
    import cv2

    from ._mkl import mkl_blas

    cv2.setNumThreads(1)
    mkl = mkl_blas()
    if mkl is not None:
        mkl.set_num_threads_local(1)


def _call_recording_warnings(function: Callable[..., Any], args: tuple[Any, ...]) -> tuple[Any, list[Any]]:
    """``function(*args)`` and the warnings it raised (a worker's warnings do not reach the parent by themselves)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = function(*args)
    return result, [(w.category, str(w.message)) for w in caught]


class ProcessMap:
    """Calls a function on each item, on worker processes, results in order (see :func:`process_map`)."""

    workers: int
    """How many processes do the work (1: this one)."""

    def __init__(self, executor: ProcessPoolExecutor | None, workers: int, progress: bool) -> None:
        self._executor = executor
        self._progress = progress
        self.workers = workers

    def __call__(self, function: Callable[..., Any], items: Sequence[tuple[Any, ...]], *, desc: str) -> list[Any]:
        """``[function(*item) for item in items]``; the workers' warnings are raised again here, in order.

        ``function`` must be importable by name (a module-level function or a
        :func:`functools.partial` of one) and its arguments and result
        picklable. The first error a worker raises is raised here, and the
        work not yet started is cancelled.
        """
        bar = tqdm(total=len(items), desc=desc, disable=not self._progress, leave=False)
        try:
            if self._executor is None:
                out = []
                for item in items:
                    out.append(function(*item))
                    bar.update()
                return out
            futures: list[Future[Any]] = [self._executor.submit(_call_recording_warnings, function, item)
                                          for item in items]
            for future in futures:
                future.add_done_callback(lambda _: bar.update())
            try:
                done = [future.result() for future in futures]
            except BaseException:
                for future in futures:
                    future.cancel()
                raise
            results = []
            for result, caught in done:
                for category, message in caught:
                    warnings.warn(message, category, stacklevel=3)
                results.append(result)
            return results
        finally:
            bar.close()


@contextmanager
def process_map(workers: int, *, progress: bool = False) -> Iterator[ProcessMap]:
    """A :class:`ProcessMap` over ``workers`` processes, started here and stopped on exit.

    ``workers`` is capped at the cores this process may use; 1 runs
    everything in this process (no start-up, nothing pickled). Workers are spawned, not forked (a fork copies MKL's and
    OpenCV's thread pools in whatever state they are in), and each runs its
    libraries on one thread. Starting one costs about a second (it imports
    the package), so callers use processes only for work of several seconds
    a piece.
    """
    workers = min(int(workers), available_cores())
    if workers <= 1:
        yield ProcessMap(None, 1, progress)
        return
    executor = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_one_thread_each)
    try:
        yield ProcessMap(executor, workers, progress)
    finally:
        executor.shutdown(wait=True, cancel_futures=True)
