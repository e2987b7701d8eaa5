"""The frame runner against real Dask clusters: a worker killed mid-run, a run killed and resumed, warm starts.

The truth is each stage's frames computed directly, frame by frame, outside the
runner (``reference_frame``, ``chain_step``), and the ``'synchronous'`` run in
this process (the single-process run of the issue's bar); the count of
recomputed chunks comes from the stage's own call log, not from the runner.
"""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from distributed import Client, LocalCluster

from facecap import InputError
from facecap.runner import FrameRun, read_chunk, run_frames
from runner_stages import FailWhileFlagged, SlowStage, WarmStage, calls, chain_step, reference_frame

HERE = Path(__file__).resolve().parent
N_FRAMES, CHUNK = 120, 8  # 15 chunks of about 0.2 s each
SEED, N_VALUES, ITERATIONS = 7, 10_000, 100


def _cluster() -> LocalCluster:
    return LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                        silence_logs=logging.ERROR)


@pytest.fixture(scope="module")
def cluster_address():
    """One two-process cluster shared by the tests that do not kill its workers."""
    with _cluster() as cluster:
        yield cluster.scheduler_address


def _truth(n_frames: int = N_FRAMES) -> np.ndarray:
    return np.stack([reference_frame(SEED, f, N_VALUES, ITERATIONS) for f in range(n_frames)])


@pytest.fixture(scope="module")
def truth() -> np.ndarray:
    return _truth()


def _stage(log_dir: Path | None = None) -> SlowStage:
    if log_dir is not None:
        log_dir.mkdir(exist_ok=True)
    return SlowStage(SEED, n_values=N_VALUES, iterations=ITERATIONS, log_dir=None if log_dir is None else str(log_dir))


def _finished(work: Path) -> list[Path]:
    return sorted((work / "chunks").glob("chunk-*.npz"))


def test_a_worker_killed_mid_chunk_changes_no_frame(tmp_path: Path, truth: np.ndarray) -> None:
    """The issue's bar: 120 frames, two worker processes, one SIGKILLed in the middle of a chunk."""
    single = run_frames(_stage(), N_FRAMES, tmp_path / "single", chunk_frames=CHUNK, scheduler="synchronous",
                        progress=False)
    np.testing.assert_array_equal(single.load("values"), truth)

    log_dir = tmp_path / "log"
    work = tmp_path / "cluster"
    killed: dict[str, int] = {}

    def kill_one_worker_mid_chunk(client: Client) -> None:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            pids = set(client.run(os.getpid).values())
            if len(_finished(work)) >= 3:
                ended = {path.stem for path in log_dir.glob("*.end")}
                running = [path for path in log_dir.glob("*.start") if path.stem not in ended]
                for path in running:
                    start, pid, _ = path.stem.split("-")
                    if int(pid) in pids:
                        os.kill(int(pid), signal.SIGKILL)
                        killed.update(start=int(start), pid=int(pid), finished=len(_finished(work)))
                        return
            time.sleep(0.01)

    with _cluster() as cluster, Client(cluster) as watcher:
        thread = threading.Thread(target=kill_one_worker_mid_chunk, args=(watcher,), daemon=True)
        thread.start()
        run = run_frames(_stage(log_dir), N_FRAMES, work, chunk_frames=CHUNK, scheduler=cluster.scheduler_address,
                         progress=False)
        thread.join(timeout=5)
        assert len(watcher.run(os.getpid)) == 2  # the nanny replaced the killed worker

    assert killed, "no worker was killed while a chunk ran (the run finished first?)"
    assert 3 <= killed["finished"] < N_FRAMES // CHUNK
    # The killed process started its chunk and never ended it; another process did.
    started, ended = calls(log_dir, "start"), calls(log_dir, "end")
    assert (killed["start"], killed["pid"]) in started and (killed["start"], killed["pid"]) not in ended
    assert any(start == killed["start"] and pid != killed["pid"] for start, pid in ended)
    with pytest.raises(ProcessLookupError):
        os.kill(killed["pid"], 0)
    assert run.computed == tuple(range(N_FRAMES // CHUNK)) and run.reused == ()
    np.testing.assert_array_equal(run.load("values"), single.load("values"))
    np.testing.assert_array_equal(run.load("frame"), np.arange(N_FRAMES))
    # Chunk for chunk, the same bytes as the single-process run (the chunk file is deterministic).
    for a, b in zip(_finished(work), _finished(tmp_path / "single"), strict=True):
        assert a.name == b.name and a.read_bytes() == b.read_bytes()
    assert not list((work / "chunks").glob(".*partial*"))


_INTERRUPTED_RUN = """
import sys
from facecap.runner import run_frames
from runner_stages import SlowStage
run_frames(SlowStage({seed}, n_values={n_values}, iterations={iterations}, log_dir=sys.argv[2]), {n_frames},
           sys.argv[1], chunk_frames={chunk}, n_workers=2, progress=False)
"""


def test_a_killed_run_resumes_without_recomputing_a_finished_chunk(
    tmp_path: Path, truth: np.ndarray, cluster_address: str
) -> None:
    """The issue's bar: the whole run (client and its local cluster) SIGKILLed, then started again."""
    work, first_log, second_log = tmp_path / "work", tmp_path / "log1", tmp_path / "log2"
    first_log.mkdir()
    script = _INTERRUPTED_RUN.format(seed=SEED, n_values=N_VALUES, iterations=ITERATIONS, n_frames=N_FRAMES,
                                     chunk=CHUNK)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")])}
    output = tmp_path / "output.txt"
    with open(output, "wb") as sink:
        process = subprocess.Popen([sys.executable, "-c", script, str(work), str(first_log)], env=env,
                                   start_new_session=True, stdout=sink, stderr=subprocess.STDOUT)
        try:
            deadline = time.monotonic() + 60
            while len(_finished(work)) < 4 and process.poll() is None and time.monotonic() < deadline:
                time.sleep(0.01)
            assert process.poll() is None, output.read_text()
        finally:
            os.killpg(process.pid, signal.SIGKILL)  # the client, its scheduler, nannies and workers at once
            process.wait()
    time.sleep(0.2)
    before = {path.name: (path.stat().st_ino, path.stat().st_mtime_ns) for path in _finished(work)}
    n_total = N_FRAMES // CHUNK
    assert 4 <= len(before) < n_total
    finished_starts = {read_chunk(path, header_only=True).header["start"] for path in _finished(work)}

    run = run_frames(_stage(second_log), N_FRAMES, work, chunk_frames=CHUNK, scheduler=cluster_address,
                     progress=False)

    starts_now = [start for start, _ in calls(second_log, "start")]
    assert not finished_starts & set(starts_now), "a finished chunk was computed again"
    assert sorted(set(starts_now)) == sorted(set(range(0, N_FRAMES, CHUNK)) - finished_starts)
    for name, (inode, mtime) in before.items():  # the finished files were not rewritten either
        stat = (work / "chunks" / name).stat()
        assert (stat.st_ino, stat.st_mtime_ns) == (inode, mtime)
    assert len(run.reused) == len(before) and len(run.computed) == n_total - len(before)
    np.testing.assert_array_equal(run.load("values"), truth)
    assert not list((work / "chunks").glob(".*partial*"))  # the killed writers' leftovers are gone


def test_a_failing_chunk_keeps_the_others_and_a_rerun_finishes(tmp_path: Path, cluster_address: str) -> None:
    n_frames, chunk = 48, 8
    flag = tmp_path / "fail"
    flag.touch()
    stage = FailWhileFlagged(_stage(tmp_path / "log1"), fail_start=16, flag=str(flag))
    with pytest.raises(RuntimeError, match="interrupted at frame 16") as failure:
        run_frames(stage, n_frames, tmp_path / "work", chunk_frames=chunk, scheduler=cluster_address,
                   progress=False)
    assert any("chunk 2 (frames 16-24)" in note for note in getattr(failure.value, "__notes__", []))
    time.sleep(0.5)  # a chunk already running on the cluster when the error came may still finish: harmless
    kept = {read_chunk(p, header_only=True).header["start"] for p in _finished(tmp_path / "work")}
    assert 16 not in kept and kept
    flag.unlink()
    rerun = FailWhileFlagged(_stage(tmp_path / "log2"), fail_start=16, flag=str(flag))
    run = run_frames(rerun, n_frames, tmp_path / "work", chunk_frames=chunk, scheduler=cluster_address,
                     progress=False)
    assert set(run.reused) == {start // chunk for start in kept}
    assert sorted(start for start, _ in calls(tmp_path / "log2")) == sorted(set(range(0, n_frames, chunk)) - kept)
    np.testing.assert_array_equal(run.load("values"), _truth(n_frames))


def _chain_truth(n_frames: int, n_values: int, restart_every: int | None) -> np.ndarray:
    """Frame after frame, restarting from zeros at every segment start."""
    frames, x = [], np.zeros(n_values)
    for frame in range(n_frames):
        if restart_every is not None and frame % restart_every == 0:
            x = np.zeros(n_values)
        x = chain_step(x, frame)
        frames.append(x)
    return np.stack(frames)


@pytest.mark.parametrize("segment_chunks", [None, 2, 1])
def test_warm_started_frames_follow_the_chain(tmp_path: Path, cluster_address: str, segment_chunks: int | None) -> None:
    n_frames, chunk = 45, 5
    run = run_frames(WarmStage(), n_frames, tmp_path, chunk_frames=chunk, segment_chunks=segment_chunks,
                     scheduler=cluster_address, progress=False)
    restart_every = None if segment_chunks is None else segment_chunks * chunk
    np.testing.assert_array_equal(run.load("x"), _chain_truth(n_frames, 64, restart_every))


def test_a_warm_started_chain_resumes_from_the_saved_state(tmp_path: Path, cluster_address: str) -> None:
    n_frames, chunk = 40, 5
    flag, log_dir = tmp_path / "fail", tmp_path / "log"
    flag.touch()
    log_dir.mkdir()
    stage = FailWhileFlagged(WarmStage(log_dir=str(log_dir)), fail_start=25, flag=str(flag))
    with pytest.raises(RuntimeError):
        run_frames(stage, n_frames, tmp_path / "work", chunk_frames=chunk, segment_chunks=None,
                   scheduler=cluster_address, progress=False)
    # One chain: the chunks before the failure are done, none after it started.
    assert [start for start, _ in calls(log_dir)] == [0, 5, 10, 15, 20]
    flag.unlink()
    run = run_frames(stage, n_frames, tmp_path / "work", chunk_frames=chunk, segment_chunks=None,
                     scheduler="synchronous", progress=False)
    assert run.reused == (0, 1, 2, 3, 4) and run.computed == (5, 6, 7)
    assert [start for start, _ in calls(log_dir)] == [0, 5, 10, 15, 20, 25, 30, 35]
    np.testing.assert_array_equal(run.load("x"), _chain_truth(n_frames, 64, None))


def test_a_finished_run_started_again_computes_nothing(tmp_path: Path, cluster_address: str) -> None:
    log_dir = tmp_path / "log"
    first = run_frames(_stage(log_dir), 24, tmp_path / "work", chunk_frames=CHUNK, scheduler=cluster_address,
                       progress=False)
    n_calls = len(calls(log_dir))
    again = run_frames(_stage(log_dir), 24, tmp_path / "work", chunk_frames=CHUNK, scheduler=cluster_address,
                       progress=False)
    assert len(calls(log_dir)) == n_calls == 3
    assert again.computed == () and again.reused == (0, 1, 2)
    np.testing.assert_array_equal(again.load("values", mmap=False), first.load("values"))
    # The blocks straight from the chunks, without the assembled file.
    blocks = list(again.blocks("values"))
    assert [start for start, _ in blocks] == [0, 8, 16]
    np.testing.assert_array_equal(np.concatenate([b for _, b in blocks]), _truth(24))


def test_without_assembly_the_frames_come_from_the_chunks(tmp_path: Path) -> None:
    run = run_frames(_stage(), 20, tmp_path, chunk_frames=6, scheduler="synchronous", assemble=False,
                     progress=False)
    assert run.arrays == {} and not list(tmp_path.glob("*.npy"))
    assert run.array_specs == {"values": (np.dtype(np.float64), (N_VALUES,)), "frame": (np.dtype(np.int64), ())}
    np.testing.assert_array_equal(run.load("values"), _truth(20))
    with pytest.raises(InputError, match="no result 'missing'"):
        run.load("missing")


def test_the_run_record_names_the_chunk_files(tmp_path: Path) -> None:
    run = run_frames(_stage(), 10, tmp_path, chunk_frames=4, scheduler="synchronous", progress=False)
    assert isinstance(run, FrameRun)
    assert [p.name for p in _finished(tmp_path)] == [run.chunk_path(i).name for i in range(3)]
    assert run.arrays == {"values": tmp_path.resolve() / "values.npy", "frame": tmp_path.resolve() / "frame.npy"}
