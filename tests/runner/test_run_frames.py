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
from facecap.runner import FrameRun, read_chunk, run_chunk, run_frames
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
def truth(tmp_path_factory: pytest.TempPathFactory) -> np.ndarray:
    """The single-process run (the bar's reference), checked frame for frame against direct computation."""
    single = run_frames(_stage(), N_FRAMES, tmp_path_factory.mktemp("single"), chunk_frames=CHUNK,
                        scheduler="synchronous", progress=False)
    frames = np.array(single.load("values"))
    sample = [0, 1, CHUNK - 1, CHUNK, 57, N_FRAMES - 1]
    np.testing.assert_array_equal(frames[sample], [reference_frame(SEED, f, N_VALUES, ITERATIONS) for f in sample])
    np.testing.assert_array_equal(single.load("frame"), np.arange(N_FRAMES))
    return frames


def _stage(log_dir: Path | None = None) -> SlowStage:
    if log_dir is not None:
        log_dir.mkdir(exist_ok=True)
    return SlowStage(SEED, n_values=N_VALUES, iterations=ITERATIONS, log_dir=None if log_dir is None else str(log_dir))


def _finished(work: Path) -> list[Path]:
    return sorted((work / "chunks").glob("chunk-*.npz"))


def test_a_worker_killed_mid_chunk_changes_no_frame(tmp_path: Path, truth: np.ndarray) -> None:
    """The issue's bar: 120 frames, two worker processes, one SIGKILLed in the middle of a chunk."""

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
        watcher.wait_for_workers(2, timeout=30)  # the nanny replaced the killed worker
        assert killed.get("pid") not in watcher.run(os.getpid).values()

    assert killed, "no worker was killed while a chunk ran (the run finished first?)"
    assert 3 <= killed["finished"] < N_FRAMES // CHUNK
    # The killed process started its chunk and never ended it; another process did.
    started, ended = calls(log_dir, "start"), calls(log_dir, "end")
    assert (killed["start"], killed["pid"]) in started and (killed["start"], killed["pid"]) not in ended
    assert any(start == killed["start"] and pid != killed["pid"] for start, pid in ended)
    with pytest.raises(ProcessLookupError):
        os.kill(killed["pid"], 0)
    assert run.computed == tuple(range(N_FRAMES // CHUNK)) and run.reused == ()
    np.testing.assert_array_equal(run.load("values"), truth)  # the single-process run, bit for bit
    np.testing.assert_array_equal(run.load("frame"), np.arange(N_FRAMES))
    # Chunk for chunk, the same bytes as a chunk computed alone in this process (the file is deterministic).
    for index in (0, N_FRAMES // CHUNK - 1):
        alone = run_chunk(_stage(), run.chunks[index], tmp_path / "alone.npz", run_id=read_chunk(
            run.chunk_path(index), header_only=True).header["run_id"])
        assert alone.read_bytes() == run.chunk_path(index).read_bytes()
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


def test_the_run_record_names_the_chunk_files(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = run_frames(_stage(), 10, tmp_path, chunk_frames=4, scheduler="synchronous", progress=True)
    assert "frame chunks" in capsys.readouterr().err  # the progress bar over chunks
    assert isinstance(run, FrameRun)
    assert [p.name for p in _finished(tmp_path)] == [run.chunk_path(i).name for i in range(3)]
    assert run.arrays == {"values": tmp_path.resolve() / "values.npy", "frame": tmp_path.resolve() / "frame.npy"}


def _chunk_stats(work: Path) -> dict[str, tuple[int, int]]:
    return {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in _finished(work)}


def test_a_resume_with_other_parameters_or_chunking_is_refused(tmp_path: Path) -> None:
    work = tmp_path / "work"
    run_frames(_stage(), 12, work, chunk_frames=4, scheduler="synchronous", progress=False)
    before = _chunk_stats(work)
    other_seed = SlowStage(SEED + 1, n_values=N_VALUES, iterations=ITERATIONS)
    with pytest.raises(InputError, match=rf"parameter seed: {SEED} before, {SEED + 1} now"):
        run_frames(other_seed, 12, work, chunk_frames=4, scheduler="synchronous", progress=False)
    with pytest.raises(InputError, match="chunk_frames: 4 before, 6 now"):
        run_frames(_stage(), 12, work, chunk_frames=6, scheduler="synchronous", progress=False)
    with pytest.raises(InputError, match="n_frames: 12 before, 16 now"):
        run_frames(_stage(), 16, work, chunk_frames=4, scheduler="synchronous", progress=False)
    with pytest.raises(InputError, match="segment_chunks: 1 before, None now"):
        run_frames(_stage(), 12, work, chunk_frames=4, segment_chunks=None, scheduler="synchronous", progress=False)
    with pytest.raises(InputError, match="stage: 'runner_stages.SlowStage' before, 'runner_stages.WarmStage' now"):
        run_frames(WarmStage(), 12, work, chunk_frames=4, scheduler="synchronous", progress=False)
    assert _chunk_stats(work) == before  # nothing was touched by the refusals
    run = run_frames(other_seed, 12, work, chunk_frames=4, scheduler="synchronous", restart=True, progress=False)
    assert run.computed == (0, 1, 2)
    expected = np.stack([reference_frame(SEED + 1, f, N_VALUES, ITERATIONS) for f in range(12)])
    np.testing.assert_array_equal(run.load("values"), expected)


def test_chunks_without_a_manifest_are_not_adopted(tmp_path: Path) -> None:
    work = tmp_path / "work"
    run_frames(_stage(), 8, work, chunk_frames=4, scheduler="synchronous", progress=False)
    (work / "manifest.json").unlink()
    with pytest.raises(InputError, match="holds chunks but no manifest.json"):
        run_frames(_stage(), 8, work, chunk_frames=4, scheduler="synchronous", progress=False)


def test_a_second_run_on_the_same_folder_at_the_same_time_is_refused(tmp_path: Path) -> None:
    import fcntl

    tmp_path.joinpath(".lock").touch()
    with open(tmp_path / ".lock") as held:
        fcntl.flock(held, fcntl.LOCK_EX | fcntl.LOCK_NB)
        with pytest.raises(InputError, match="another run is using this work folder"):
            run_frames(_stage(), 4, tmp_path, chunk_frames=4, scheduler="synchronous", progress=False)
    run_frames(_stage(), 4, tmp_path, chunk_frames=4, scheduler="synchronous", progress=False)


class _ShapeChangesAtFrame8:
    def parameters(self) -> dict[str, int]:
        return {}

    def __call__(self, start: int, stop: int, state: object):
        return {"values": np.zeros((stop - start, 3 if start < 8 else 4), np.float32)}, None


def test_chunks_that_disagree_on_their_arrays_are_an_error(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"different arrays for chunk 2 .*values float32 \(4,\) there"):
        run_frames(_ShapeChangesAtFrame8(), 12, tmp_path, chunk_frames=4, scheduler="synchronous", progress=False)
    assert not list(tmp_path.glob("*.npy"))


def test_a_damaged_chunk_is_recomputed_with_a_warning(tmp_path: Path) -> None:
    from facecap import FacecapWarning

    run_frames(_stage(), 12, tmp_path, chunk_frames=4, scheduler="synchronous", progress=False)
    damaged = _finished(tmp_path)[1]
    damaged.write_bytes(damaged.read_bytes()[:1000])  # what a crash of the machine could leave
    with pytest.warns(FacecapWarning, match="recomputing a damaged chunk"):
        run = run_frames(_stage(), 12, tmp_path, chunk_frames=4, scheduler="synchronous", progress=False)
    assert run.computed == (1,) and run.reused == (0, 2)
    np.testing.assert_array_equal(run.load("values"), _truth(12))


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ({"n_frames": 0}, "n_frames: expected an integer >= 1"),
        ({"chunk_frames": 2.5}, "chunk_frames: expected an integer >= 1"),
        ({"segment_chunks": 0}, "segment_chunks: expected an integer >= 1"),
        ({"scheduler": 8786}, "scheduler must be None, 'synchronous' or an address"),
        ({"n_workers": 0, "scheduler": None}, "n_workers: expected an integer >= 1"),
    ],
)
def test_bad_arguments_are_clear_errors(tmp_path: Path, arguments: dict, message: str) -> None:
    options = {"n_frames": 8, "chunk_frames": 4, "scheduler": "synchronous", **arguments}
    n_frames = options.pop("n_frames")
    with pytest.raises(InputError, match=message):
        run_frames(_stage(), n_frames, tmp_path / "work", progress=False, **options)


def test_a_work_folder_that_is_a_file_is_refused(tmp_path: Path) -> None:
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError, match="the work folder is a file"):
        run_frames(_stage(), 4, tmp_path / "file", scheduler="synchronous", progress=False)


def test_the_callers_default_dask_client_is_neither_used_nor_replaced(tmp_path: Path, cluster_address: str) -> None:
    """A caller with a Dask client of its own (on its own event loop) keeps it as the default."""
    from distributed import default_client

    with Client(cluster_address) as mine:
        run = run_frames(_stage(), 16, tmp_path, chunk_frames=4, scheduler=cluster_address, progress=False)
        assert default_client() is mine
    np.testing.assert_array_equal(run.load("values"), _truth(16))


def test_a_chunk_that_kills_its_workers_fails_the_run_clearly(tmp_path: Path) -> None:
    """A crash in compiled code or the OOM killer: Dask gives up on the chunk (here at the first death)."""
    import dask

    from facecap import SolverError
    from runner_stages import ExitsTheWorker

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), _cluster() as cluster:
        started = time.monotonic()
        with pytest.raises(SolverError, match=r"chunk \d \(frames \d+-\d+\) killed every worker that ran it"):
            run_frames(ExitsTheWorker(), 8, tmp_path, chunk_frames=4, scheduler=cluster.scheduler_address,
                       progress=False)
        assert time.monotonic() - started < 30
    assert not list((tmp_path / "chunks").glob("chunk-*"))
