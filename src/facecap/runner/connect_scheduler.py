"""Where the frame runner's chunks run: a local Dask cluster, an existing one, or this process."""

from __future__ import annotations

import gc
import logging
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from ..errors import InputError
from ..validate import as_count

__all__ = ["SYNCHRONOUS", "connect_scheduler"]

#: The ``scheduler`` value that runs every chunk in the calling process, in order.
SYNCHRONOUS = "synchronous"


@contextmanager
def connect_scheduler(
    scheduler: str | None = None, *, n_workers: int = 2, connect_timeout_s: float = 10.0
) -> Iterator[Any]:
    """Open a Dask client for the frame runner; close what was opened on exit.

    Parameters
    ----------
    scheduler : str or None, optional
        None (default): start a ``distributed.LocalCluster`` of ``n_workers``
        worker processes with one thread each (the stages are CPU-bound numpy and
        release the GIL unevenly; processes isolate them), closed on exit.
        ``'synchronous'``: no Dask at all; yields None and the caller runs every
        chunk in this process. Any other string: the address of a running Dask
        scheduler, ``tcp://host:8786`` (started with ``dask scheduler``), whose
        workers must see the work folder at the same path.
    n_workers : int, optional
        Worker processes of the local cluster, default 2; ignored otherwise.
    connect_timeout_s : float, optional
        How long to wait for a scheduler address to answer, default 10 s.

    Yields
    ------
    client : distributed.Client or None
        None for ``'synchronous'``.

    Raises
    ------
    InputError
        If the address is malformed, nothing answers there within
        ``connect_timeout_s``, or the arguments are out of range.
    """
    if scheduler is not None and not isinstance(scheduler, str):
        raise InputError(f"scheduler must be None, 'synchronous' or an address string; got {type(scheduler).__name__}")
    if scheduler == SYNCHRONOUS:
        yield None
        return
    if not connect_timeout_s > 0:
        raise InputError(f"connect_timeout_s must be positive; got {connect_timeout_s!r}")
    from distributed import Client, LocalCluster

    # Not the process's default client: the caller's own Dask work keeps its client,
    # and the runner names its client wherever Dask would otherwise look one up.
    if scheduler is None:
        n_workers = as_count(n_workers, name="n_workers")
        # A random dashboard port: the fixed default (8787) collides with any other
        # cluster on the machine, and distributed then warns.
        with LocalCluster(
            n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=":0",
            silence_logs=logging.ERROR,
        ) as cluster, Client(cluster, set_as_default=False) as client:
            yield client
        return
    address = scheduler.strip()
    if not address:
        raise InputError("scheduler address is empty; give tcp://HOST:PORT, 'synchronous', or nothing")
    failure = None
    try:
        client = Client(address, timeout=connect_timeout_s, set_as_default=False)
    except (OSError, ValueError, TimeoutError) as exc:
        failure = str(exc)
    if failure is not None:
        # The Client that failed to connect is left in a reference cycle; if the
        # garbage collector ran its __del__ later, inside the start of another
        # cluster, the two would deadlock on distributed's loop-runner lock.
        # Collect it here, where no lock is held.
        gc.collect()
        raise InputError(
            f"cannot reach the Dask scheduler at {address!r} within {connect_timeout_s:g} s ({failure}); "
            "start one with 'dask scheduler' and workers with 'dask worker ADDRESS', "
            "or leave --scheduler out to run on a local cluster"
        )
    try:
        yield client
    finally:
        client.close()
