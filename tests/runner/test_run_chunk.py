"""One chunk: computed twice (in turn and at the same time) it leaves the same bytes; its file reads back.

Truth: the stage's frames computed directly (``reference_frame``), numpy's own
``.npz`` reader and the ZIP checksums of the standard library.
"""

from __future__ import annotations

import multiprocessing
import zipfile
from pathlib import Path

import numpy as np
import pytest

from facecap import FileFormatError, InputError
from facecap.runner import CHUNK_FORMAT, FrameChunk, chunk_file_name, plan_chunks, read_chunk, run_chunk
from runner_stages import SlowStage, WarmStage, calls, reference_frame

SEED, N_VALUES, ITERATIONS = 3, 5_000, 60
CHUNK = FrameChunk(index=1, start=10, stop=20, segment=1, previous=None)


def _stage(log_dir: Path | None = None) -> SlowStage:
    return SlowStage(SEED, n_values=N_VALUES, iterations=ITERATIONS, log_dir=None if log_dir is None else str(log_dir))


def _truth(start: int, stop: int) -> np.ndarray:
    return np.stack([reference_frame(SEED, f, N_VALUES, ITERATIONS) for f in range(start, stop)])


def test_the_chunk_file_is_an_npz_numpy_reads(tmp_path: Path) -> None:
    path = run_chunk(_stage(), CHUNK, tmp_path / chunk_file_name(CHUNK), run_id="run-a")
    with np.load(path) as npz:  # numpy's own reader: the file is a plain .npz
        np.testing.assert_array_equal(npz["frames/values"], _truth(10, 20))
        np.testing.assert_array_equal(npz["frames/frame"], np.arange(10, 20))
    with zipfile.ZipFile(path) as archive:
        assert archive.testzip() is None  # every member's CRC checks
        assert {info.compress_type for info in archive.infolist()} == {zipfile.ZIP_STORED}
    contents = read_chunk(path, run_id="run-a", chunk=CHUNK)
    assert contents.state is None
    assert contents.header["format"] == CHUNK_FORMAT
    assert contents.header["arrays"]["values"] == {"dtype": "<f8", "shape": [10, N_VALUES]}
    np.testing.assert_array_equal(contents.arrays["values"], _truth(10, 20))


def test_a_chunk_computed_twice_in_turn_gives_the_same_bytes(tmp_path: Path) -> None:
    path = tmp_path / chunk_file_name(CHUNK)
    first = run_chunk(_stage(tmp_path), CHUNK, path, run_id="run-a").read_bytes()
    second = run_chunk(_stage(tmp_path), CHUNK, path, run_id="run-a").read_bytes()
    assert len(calls(tmp_path, "end")) == 2  # computed twice, not skipped
    assert first == second
    assert [p.name for p in tmp_path.iterdir() if p.suffix == ".npz" or "partial" in p.name] == [path.name]


def _long_stage(log_dir: str | None = None) -> SlowStage:
    """About 0.2 s a chunk: long enough for two processes released together to overlap."""
    return SlowStage(SEED, n_values=10_000, iterations=100, log_dir=log_dir)


def _compute_after(barrier, path: str, log_dir: str) -> None:
    barrier.wait()
    run_chunk(_long_stage(log_dir), CHUNK, path, run_id="run-a")


def test_a_chunk_computed_twice_at_the_same_time_is_harmless(tmp_path: Path) -> None:
    """Two processes (a task Dask started again while the first was still running) write the same chunk."""
    alone = run_chunk(_long_stage(), CHUNK, tmp_path / "alone.npz", run_id="run-a").read_bytes()
    path, log_dir = tmp_path / "shared" / chunk_file_name(CHUNK), tmp_path / "log"
    path.parent.mkdir()
    log_dir.mkdir()
    context = multiprocessing.get_context("spawn")
    barrier = context.Barrier(2)
    processes = [context.Process(target=_compute_after, args=(barrier, str(path), str(log_dir))) for _ in range(2)]
    for process in processes:
        process.start()
    for process in processes:
        process.join(60)
    assert [process.exitcode for process in processes] == [0, 0]
    starts = sorted(p.stat().st_mtime_ns for p in log_dir.glob("*.start"))
    ends = sorted(p.stat().st_mtime_ns for p in log_dir.glob("*.end"))
    assert len(starts) == len(ends) == 2 and starts[1] < ends[0]  # both were computing at once
    assert path.read_bytes() == alone
    assert sorted(p.name for p in path.parent.iterdir()) == [path.name]  # no partial left behind


def test_a_warm_started_chunk_reads_its_state_from_the_previous_file(tmp_path: Path) -> None:
    first, second = plan_chunks(8, chunk_frames=4, segment_chunks=2)
    stage = WarmStage(8)
    a = run_chunk(stage, first, tmp_path / chunk_file_name(first), run_id="r")
    b = run_chunk(stage, second, tmp_path / chunk_file_name(second), run_id="r", previous=a)
    whole, _ = stage(0, 8, None)
    joined = np.concatenate([read_chunk(a).arrays["x"], read_chunk(b).arrays["x"]])
    np.testing.assert_array_equal(joined, whole["x"])
    np.testing.assert_array_equal(read_chunk(a).state["x"], whole["x"][3])
    with pytest.raises(InputError, match="give its file as previous"):
        run_chunk(stage, second, tmp_path / "x.npz", run_id="r")
    with pytest.raises(InputError, match="starts its segment cold"):
        run_chunk(stage, first, tmp_path / "x.npz", run_id="r", previous=a)
    with pytest.raises(FileFormatError, match="belongs to run 'r', not to this run 'other'"):
        run_chunk(stage, second, tmp_path / "x.npz", run_id="other", previous=a)
    not_before = FrameChunk(index=2, start=12, stop=16, segment=0, previous=0)
    with pytest.raises(InputError, match="does not continue chunk 0"):
        run_chunk(stage, not_before, tmp_path / "x.npz", run_id="r", previous=a)


class _Returns:
    def __init__(self, result):
        self.result = result

    def __call__(self, start, stop, state):
        return self.result


@pytest.mark.parametrize(
    ("result", "message"),
    [
        ({"values": np.zeros((10, 2))}, r"must return \(arrays, state\)"),
        (({"values": np.zeros((9, 2))}, None), "its first axis must be the 10 frames"),
        (({"values": np.float64(1.0)}, None), "its first axis must be the 10 frames"),
        (({}, None), "returned no arrays"),
        (({"bad name": np.zeros(10)}, None), "names must be Python identifiers"),
        (({"values": np.array([object()] * 10)}, None), "dtype object"),
        (([np.zeros(10)], None), "must be a dict of name -> numpy array"),
        (({"values": np.zeros(10)}, [1, 2]), "the state of .* must be a dict"),
    ],
)
def test_a_stage_returning_something_else_is_a_clear_error(tmp_path: Path, result, message: str) -> None:
    with pytest.raises(InputError, match=message):
        run_chunk(_Returns(result), CHUNK, tmp_path / "c.npz", run_id="r")
    assert list(tmp_path.iterdir()) == []  # nothing written, not even a partial


def test_unreadable_or_foreign_chunk_files_are_format_errors(tmp_path: Path) -> None:
    path = run_chunk(_stage(), CHUNK, tmp_path / "c.npz", run_id="run-a")
    with pytest.raises(FileFormatError, match="holds chunk 1 .*not chunk 0"):
        read_chunk(path, chunk=FrameChunk(0, 0, 10, 0, None))
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(path.read_bytes()[:-100])
    with pytest.raises(FileFormatError, match="unreadable chunk file"):
        read_chunk(truncated)
    with pytest.raises(FileFormatError, match="does not exist"):
        read_chunk(tmp_path / "missing.npz")
    other = tmp_path / "other.npz"
    np.savez(other, values=np.zeros(3))
    with pytest.raises(FileFormatError, match="unreadable chunk file"):
        read_chunk(other)
