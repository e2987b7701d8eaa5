"""Schedulers: a bad or silent address is a clear error within its timeout; a scheduler without workers too."""

from __future__ import annotations

import logging
import os
import socket
import time
from pathlib import Path

import pytest
from distributed import LocalCluster

from facecap import InputError
from facecap.runner import SYNCHRONOUS, connect_scheduler, run_frames
from runner_stages import SlowStage


def _closed_port() -> int:
    """A local port nothing listens on (bound, then released)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_synchronous_needs_no_dask() -> None:
    with connect_scheduler(SYNCHRONOUS) as client:
        assert client is None


def test_an_address_where_nothing_answers_fails_within_the_timeout(tmp_path: Path) -> None:
    address = f"tcp://127.0.0.1:{_closed_port()}"
    started = time.monotonic()
    with pytest.raises(InputError, match=rf"cannot reach the Dask scheduler at '{address}' within 1 s"):
        run_frames(SlowStage(1), 4, tmp_path, scheduler=address, connect_timeout_s=1.0, progress=False)
    assert time.monotonic() - started < 5


@pytest.mark.parametrize("address", ["no-port-here", "   "])
def test_a_malformed_address_is_a_clear_error(address: str) -> None:
    with pytest.raises(InputError, match="scheduler address|cannot reach the Dask scheduler"):
        with connect_scheduler(address, connect_timeout_s=1.0):
            pass


def test_a_scheduler_without_workers_is_a_clear_error(tmp_path: Path) -> None:
    with LocalCluster(n_workers=0, processes=True, dashboard_address=":0", silence_logs=logging.ERROR) as cluster:
        started = time.monotonic()
        with pytest.raises(InputError, match="has no workers"):
            run_frames(SlowStage(1), 4, tmp_path, scheduler=cluster.scheduler_address, connect_timeout_s=1.0,
                       progress=False)
        assert time.monotonic() - started < 5


def test_the_local_cluster_has_the_workers_asked_for() -> None:
    with connect_scheduler(None, n_workers=2) as client:
        pids = client.run(os.getpid)
        assert len(pids) == 2 and os.getpid() not in pids.values()  # separate processes
        assert set(client.nthreads().values()) == {1}


@pytest.mark.parametrize(("arguments", "message"), [
    ({"scheduler": 3}, "scheduler must be None"),
    ({"scheduler": None, "n_workers": 0}, "n_workers: expected an integer >= 1"),
    ({"scheduler": "tcp://127.0.0.1:1", "connect_timeout_s": 0}, "connect_timeout_s must be positive"),
])
def test_bad_arguments(arguments: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        with connect_scheduler(**arguments):
            pass
