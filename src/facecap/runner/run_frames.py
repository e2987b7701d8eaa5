"""The frame runner: a slow per-frame stage over every frame of a take, in resumable chunks on Dask.

One home for running slow stages (the wrinkle layer, the muscle solve): the
frames are cut into chunks (:func:`~facecap.runner.plan_chunks`), each chunk is a
Dask task that computes it with the stage and writes its file atomically
(:func:`~facecap.runner.run_chunk`), and at the end the chunks are streamed into
one ``.npy`` per result array. The work folder holds::

    manifest.json        what the run computes (stage, parameters, frames, chunking)
    chunks/chunk-….npz   one finished chunk each (the file is its own done-marker)
    <name>.npy           the assembled results, (n_frames, ...) per array name

Started again on the same folder, the runner skips every finished chunk; with a
different stage, parameters or chunking it refuses (``restart=True`` discards the
old chunks instead). See ``docs/runner.md``.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import time
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from ..errors import FacecapWarning, FileFormatError, InputError, SolverError
from ..io.atomic_write import atomic_path, atomic_write_text
from .connect_scheduler import connect_scheduler
from .frame_stage import FrameStage, stage_identity
from ..validate import as_count
from .plan_chunks import FrameChunk, plan_chunks
from .run_chunk import chunk_file_name, read_chunk, run_chunk

__all__ = ["MANIFEST_FILE", "MANIFEST_FORMAT", "FrameRun", "run_frames"]

#: The work folder's record of what its chunks are (JSON).
MANIFEST_FILE = "manifest.json"
#: Format tag of :data:`MANIFEST_FILE`.
MANIFEST_FORMAT = "facecap.runner.manifest/1"
CHUNKS_FOLDER = "chunks"
# The manifest entries a resume must match; the rest (the run id derived from them) is bookkeeping.
_IDENTITY_KEYS = ("format", "stage", "parameters", "pickle_sha256", "n_frames", "chunk_frames", "segment_chunks")


@dataclass(frozen=True)
class FrameRun:
    """A finished run of the frame runner.

    Attributes
    ----------
    work_dir : pathlib.Path
        The work folder (absolute).
    n_frames : int
        Frames of the run.
    chunks : tuple of FrameChunk
        The chunks, in frame order.
    computed : tuple of int
        Indices of the chunks computed by this call (the others were found
        finished in the work folder). A chunk recomputed by Dask after a lost
        worker counts once.
    reused : tuple of int
        Indices of the chunks found finished and not recomputed.
    arrays : dict of str to pathlib.Path
        The assembled ``(n_frames, ...)`` array file of each result name (empty
        if the run was called with ``assemble=False``).
    array_specs : dict of str to (numpy.dtype, tuple)
        Dtype and per-frame shape of each result name.
    wall_seconds : float
        Wall-clock time of the call.
    """

    work_dir: Path
    n_frames: int
    chunks: tuple[FrameChunk, ...]
    computed: tuple[int, ...]
    reused: tuple[int, ...]
    arrays: dict[str, Path] = field(default_factory=dict)
    array_specs: dict[str, tuple[np.dtype, tuple[int, ...]]] = field(default_factory=dict)
    wall_seconds: float = 0.0

    def chunk_path(self, chunk: FrameChunk | int) -> Path:
        """The file of a chunk (a :class:`FrameChunk` or its index)."""
        if not isinstance(chunk, FrameChunk):
            chunk = self.chunks[chunk]
        return self.work_dir / CHUNKS_FOLDER / chunk_file_name(chunk)

    def blocks(self, name: str) -> Iterator[tuple[int, np.ndarray]]:
        """Yield ``(start, block)`` for one result name, chunk by chunk, from the chunk files.

        Parameters
        ----------
        name : str
            A result array name.

        Yields
        ------
        start : int
            First frame of the block.
        block : ndarray
            ``(stop - start, ...)`` frames of the array.
        """
        self._check_name(name)
        for chunk in self.chunks:
            yield chunk.start, read_chunk(self.chunk_path(chunk), chunk=chunk).arrays[name]

    def load(self, name: str, *, mmap: bool = True) -> np.ndarray:
        """One result array, ``(n_frames, ...)``: the assembled file, or the chunks joined.

        Parameters
        ----------
        name : str
            A result array name.
        mmap : bool, optional
            Memory-map the assembled file read-only (default True); ignored when
            the run was not assembled.
        """
        self._check_name(name)
        if name in self.arrays:
            return np.load(self.arrays[name], mmap_mode="r" if mmap else None)
        return np.concatenate([block for _, block in self.blocks(name)], axis=0)

    def _check_name(self, name: str) -> None:
        if name not in self.array_specs:
            raise InputError(f"the run has no result {name!r}; it has {sorted(self.array_specs)}")


def run_frames(
    stage: FrameStage,
    n_frames: int,
    work_dir: str | os.PathLike[str],
    *,
    chunk_frames: int = 32,
    segment_chunks: int | None = 1,
    scheduler: str | None = None,
    n_workers: int = 2,
    assemble: bool = True,
    restart: bool = False,
    connect_timeout_s: float = 10.0,
    progress: bool = True,
) -> FrameRun:
    """Run a slow per-frame stage over frames ``0 .. n_frames - 1`` in resumable chunks.

    Parameters
    ----------
    stage : FrameStage
        A picklable callable ``stage(start, stop, state) -> (arrays, state)``
        (see :class:`~facecap.runner.FrameStage`), deterministic, with a
        ``parameters()`` method naming what its frames depend on (recommended).
    n_frames : int
        Frames to compute, at least 1.
    work_dir : str or path-like
        The run's folder (created if missing): manifest, chunk files and the
        assembled arrays. On a cluster, every worker must see it at the same path.
        One run at a time per folder (a second is refused while the first holds it).
    chunk_frames : int, optional
        Frames per chunk (a task, a file, the unit of resume), default 32.
    segment_chunks : int or None, optional
        Chunks per warm-started segment (:func:`~facecap.runner.plan_chunks`),
        default 1: every chunk starts cold and all run in parallel. None: one
        chain over the whole run.
    scheduler : str or None, optional
        None (default): a local cluster of ``n_workers`` processes, closed at the
        end; ``'synchronous'``: every chunk in this process, in order (small jobs,
        debugging, the single-process reference); otherwise the address of a
        running Dask scheduler (``tcp://host:8786``).
    n_workers : int, optional
        Worker processes of the local cluster, default 2.
    assemble : bool, optional
        Stream the chunks into ``work_dir/<name>.npy`` at the end (default True).
        With False, read them with :meth:`FrameRun.blocks`.
    restart : bool, optional
        Discard the chunks of an earlier, different run in ``work_dir`` instead of
        refusing; default False.
    connect_timeout_s : float, optional
        How long a scheduler address (and its workers) may take to answer,
        default 10 s.
    progress : bool, optional
        Show a progress bar over chunks (default True).

    Returns
    -------
    FrameRun
        Where the results are, and which chunks this call computed.

    Raises
    ------
    InputError
        Bad arguments; a work folder holding chunks of another run (another
        stage, other parameters, frame count or chunking) or used by another run
        at this moment; a scheduler that does not answer, has no workers, or
        whose workers cannot see ``work_dir``; a stage returning something other
        than named arrays of the chunk's frames, or different names, dtypes or
        shapes in different chunks.
    SolverError
        If a chunk keeps killing the worker that runs it (Dask's
        ``KilledWorker``: out of memory, a crash in compiled code).
    Exception
        Whatever the stage raises, with a note naming the chunk. The chunks
        finished before it stay in ``work_dir``: run again to resume.

    Notes
    -----
    A chunk is done when its file exists under its final name: it is written under
    a temporary name and renamed (atomic), so an interrupted run, a killed worker
    or a task that Dask runs twice never leaves a partial chunk that counts.
    A worker lost mid-chunk is replaced by the cluster (a local cluster's nanny
    restarts it) and Dask reruns its task; a chunk whose worker dies three times
    (Dask's ``distributed.scheduler.allowed-failures``) fails the run.

    Examples
    --------
    >>> import numpy as np, tempfile
    >>> class Squares:
    ...     def parameters(self):
    ...         return {}
    ...     def __call__(self, start, stop, state):
    ...         frames = np.arange(start, stop, dtype=np.float64)
    ...         return {"squares": frames[:, None] ** 2}, None
    >>> run = run_frames(Squares(), 10, tempfile.mkdtemp(), chunk_frames=4,
    ...                  scheduler="synchronous", progress=False)
    >>> run.load("squares")[:, 0].tolist()
    [0.0, 1.0, 4.0, 9.0, 16.0, 25.0, 36.0, 49.0, 64.0, 81.0]
    >>> run.computed
    (0, 1, 2)
    """
    started = time.perf_counter()
    chunks = plan_chunks(n_frames, chunk_frames=chunk_frames, segment_chunks=segment_chunks)
    if scheduler is not None and not isinstance(scheduler, str):
        raise InputError(f"scheduler must be None, 'synchronous' or an address string; got {type(scheduler).__name__}")
    as_count(n_workers, name="n_workers")
    if not (isinstance(connect_timeout_s, (int, float)) and connect_timeout_s > 0):
        raise InputError(f"connect_timeout_s must be a positive number of seconds; got {connect_timeout_s!r}")
    identity = stage_identity(stage)
    manifest: dict[str, Any] = {
        "format": MANIFEST_FORMAT,
        **identity,
        "n_frames": int(n_frames),
        "chunk_frames": int(chunk_frames),
        "segment_chunks": None if segment_chunks is None else int(segment_chunks),
    }
    canonical = json.dumps({k: manifest[k] for k in _IDENTITY_KEYS if k in manifest}, sort_keys=True)
    run_id = hashlib.sha256(canonical.encode()).hexdigest()[:16]
    manifest["run_id"] = run_id

    work = Path(work_dir).resolve()
    if work.exists() and not work.is_dir():
        raise InputError("the work folder is a file", path=str(work))
    work.mkdir(parents=True, exist_ok=True)
    chunks_dir = work / CHUNKS_FOLDER
    with _exclusive_lock(work):
        _open_manifest(work, manifest, restart=restart)
        chunks_dir.mkdir(exist_ok=True)
        done = _finished_chunks(chunks_dir, chunks, run_id)
        missing = [chunk for chunk in chunks if chunk.index not in done]
        paths = {chunk.index: chunks_dir / chunk_file_name(chunk) for chunk in chunks}
        with tqdm(total=len(chunks), initial=len(done), desc="frame chunks", unit="chunk",
                  disable=not progress, leave=False) as bar:
            if missing:
                with connect_scheduler(scheduler, n_workers=n_workers, connect_timeout_s=connect_timeout_s) as client:
                    if client is None:
                        _run_here(stage, missing, paths, run_id, bar)
                    else:
                        _run_on_cluster(client, stage, missing, paths, done, run_id, bar, connect_timeout_s)
        specs = _array_specs(chunks, paths, run_id)
        arrays = _assemble(work, chunks, paths, specs, progress=progress) if assemble else {}
    return FrameRun(
        work_dir=work,
        n_frames=int(n_frames),
        chunks=tuple(chunks),
        computed=tuple(chunk.index for chunk in missing),
        reused=tuple(sorted(done)),
        arrays=arrays,
        array_specs=specs,
        wall_seconds=time.perf_counter() - started,
    )


@contextlib.contextmanager
def _exclusive_lock(work: Path) -> Iterator[None]:
    """Hold an advisory lock on the work folder: a second run on it at the same time is refused.

    ``flock`` is released by the kernel when the process dies, so a killed run
    leaves no stale lock. Where it is unavailable (Windows, some network file
    systems) the run goes ahead unlocked.
    """
    try:
        import fcntl
    except ImportError:  # Windows
        yield
        return
    with open(work / ".lock", "a") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise InputError("another run is using this work folder now; wait for it or use another folder",
                             path=str(work)) from None
        except OSError:  # no lock support on this file system
            yield
            return
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _open_manifest(work: Path, manifest: dict[str, Any], *, restart: bool) -> None:
    """Check the work folder holds this run (or nothing); write the manifest of a new run."""
    path = work / MANIFEST_FILE
    chunks_dir = work / CHUNKS_FOLDER
    if path.exists():
        try:
            old = json.loads(path.read_text(encoding="utf-8"))
            if not isinstance(old, dict):
                raise ValueError("not a JSON object")
        except (ValueError, OSError) as exc:
            raise FileFormatError(f"unreadable run manifest ({exc}); delete the work folder or pass restart",
                                  path=str(path)) from None
        differences = [
            f"{key}: {old.get(key)!r} before, {manifest.get(key)!r} now"
            for key in _IDENTITY_KEYS
            if old.get(key) != manifest.get(key)
        ]
        differences = _parameter_differences(old, manifest) or differences
        if not differences:
            return
        if not restart:
            raise InputError(
                "the work folder holds chunks of a different run, which must not be mixed with this one ("
                + "; ".join(differences) + "); use another work folder, or restart to discard them",
                path=str(work),
            )
    elif chunks_dir.is_dir() and any(chunks_dir.iterdir()) and not restart:
        raise InputError("the work folder holds chunks but no manifest.json, so it is not known what they are; "
                         "use another work folder, or restart to discard them", path=str(work))
    if chunks_dir.exists():
        shutil.rmtree(chunks_dir)
    atomic_write_text(path, json.dumps(manifest, indent=2, sort_keys=True) + "\n")


def _parameter_differences(old: dict[str, Any], new: dict[str, Any]) -> list[str]:
    """Name the parameters that changed, one by one, when both runs recorded parameters."""
    before, now = old.get("parameters"), new.get("parameters")
    if not (isinstance(before, dict) and isinstance(now, dict)) or before == now:
        return []
    others = [f"{k}: {old.get(k)!r} before, {new.get(k)!r} now"
              for k in _IDENTITY_KEYS if k != "parameters" and old.get(k) != new.get(k)]
    changed = [f"parameter {k}: {before.get(k, '(absent)')!r} before, {now.get(k, '(absent)')!r} now"
               for k in sorted(set(before) | set(now)) if before.get(k, ...) != now.get(k, ...)]
    return others + changed


def _finished_chunks(chunks_dir: Path, chunks: list[FrameChunk], run_id: str) -> set[int]:
    """Indices of the chunks whose file is finished; delete leftovers of interrupted writes."""
    for leftover in chunks_dir.glob(".chunk-*.partial-*"):
        leftover.unlink(missing_ok=True)
    done = set()
    for chunk in chunks:
        path = chunks_dir / chunk_file_name(chunk)
        if not path.exists():
            continue
        try:
            read_chunk(path, run_id=run_id, chunk=chunk, header_only=True)
        except FileFormatError as exc:  # e.g. truncated by a crash of the machine: compute it again
            warnings.warn(f"recomputing a damaged chunk: {exc}", FacecapWarning, stacklevel=3)
            path.unlink()
            continue
        done.add(chunk.index)
    return done


def _note(exc: BaseException, chunk: FrameChunk, paths: dict[int, Path]) -> None:
    if hasattr(exc, "add_note"):  # Python >= 3.11
        exc.add_note(f"facecap.runner: while computing chunk {chunk.index} (frames {chunk.start}-{chunk.stop}); "
                     f"the finished chunks are kept in {paths[chunk.index].parent}: run again to resume")


def _run_here(stage: FrameStage, missing: list[FrameChunk], paths: dict[int, Path], run_id: str, bar: tqdm) -> None:
    for chunk in missing:
        previous = None if chunk.previous is None else paths[chunk.previous]
        try:
            run_chunk(stage, chunk, paths[chunk.index], run_id=run_id, previous=previous)
        except Exception as exc:
            _note(exc, chunk, paths)
            raise
        bar.update(1)


def _chunk_task(stage: FrameStage, chunk: FrameChunk, path: str, run_id: str, previous: str | None) -> str:
    """What a worker runs: the chunk, unless a first run of this very task already finished it."""
    if not os.path.exists(path):
        run_chunk(stage, chunk, path, run_id=run_id, previous=previous)
    return path


def _the_stage(stage: FrameStage) -> FrameStage:
    return stage


def _run_on_cluster(
    client: Any,
    stage: FrameStage,
    missing: list[FrameChunk],
    paths: dict[int, Path],
    done: set[int],
    run_id: str,
    bar: tqdm,
    connect_timeout_s: float,
) -> None:
    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    try:
        client.wait_for_workers(1, timeout=connect_timeout_s)
    except TimeoutError:
        raise InputError(f"the Dask scheduler has no workers (waited {connect_timeout_s:g} s); "
                         "start some with 'dask worker ADDRESS'") from None
    folder = str(next(iter(paths.values())).parent)
    sees = client.run(os.path.isdir, folder)
    blind = sorted(worker for worker, ok in sees.items() if not ok)
    if blind:
        raise InputError(f"Dask workers {blind} cannot see the work folder at this path; put it on a file "
                         "system every worker mounts at the same path", path=folder)
    token = os.urandom(4).hex()
    # The stage travels once, as a task: the scheduler keeps its pickle, so a worker
    # lost with the stage in memory is harmless (it is recomputed), unlike scattered data.
    stage_future = client.submit(_the_stage, stage, key=f"facecap-stage-{run_id}-{token}", pure=False)
    futures: dict[Any, FrameChunk] = {}
    by_index: dict[int, Any] = {}
    for chunk in missing:
        previous: Any = None
        if chunk.previous is not None:
            previous = str(paths[chunk.previous]) if chunk.previous in done else by_index[chunk.previous]
        future = client.submit(
            _chunk_task, stage_future, chunk, str(paths[chunk.index]), run_id, previous,
            key=f"facecap-chunk-{chunk.index:06d}-{run_id}-{token}", pure=False,
            priority=len(paths) - chunk.index,  # earlier frames first, so a resume wastes little
        )
        futures[future] = chunk
        by_index[chunk.index] = future
    try:
        # This client's loop: as_completed would otherwise take the process's default client's.
        for future in as_completed(list(futures), loop=client.loop):
            chunk = futures[future]
            try:
                future.result()
            except KilledWorker as exc:
                raise SolverError(
                    f"chunk {chunk.index} (frames {chunk.start}-{chunk.stop}) killed every worker that ran it "
                    f"({exc}); out of memory, or a crash in compiled code? The finished chunks are kept: "
                    "run again to resume"
                ) from None
            except Exception as exc:
                _note(exc, chunk, paths)
                raise
            bar.update(1)
    finally:
        # Release the tasks (and stop the pending ones after an error); a failure to
        # reach the scheduler here must not hide the error that brought us here.
        with contextlib.suppress(Exception):
            client.cancel([*futures, stage_future])


def _array_specs(
    chunks: list[FrameChunk], paths: dict[int, Path], run_id: str
) -> dict[str, tuple[np.dtype, tuple[int, ...]]]:
    """The dtype and per-frame shape of each result, checked equal in every chunk."""
    specs: dict[str, tuple[np.dtype, tuple[int, ...]]] = {}
    for chunk in chunks:
        header = read_chunk(paths[chunk.index], run_id=run_id, chunk=chunk, header_only=True).header
        found = {name: (np.dtype(spec["dtype"]), tuple(spec["shape"][1:])) for name, spec in header["arrays"].items()}
        if chunk.index == 0:
            specs = found
        elif found != specs:
            raise InputError(
                f"the stage returned different arrays for chunk {chunk.index} (frames {chunk.start}-{chunk.stop}): "
                f"{_describe(found)} there, {_describe(specs)} in chunk 0; every chunk must return the same "
                "names, dtypes and per-frame shapes",
                path=str(paths[chunk.index]),
            )
    return specs


def _describe(specs: dict[str, tuple[np.dtype, tuple[int, ...]]]) -> str:
    return ", ".join(f"{name} {dtype} {shape}" for name, (dtype, shape) in sorted(specs.items()))


def _assemble(
    work: Path,
    chunks: list[FrameChunk],
    paths: dict[int, Path],
    specs: dict[str, tuple[np.dtype, tuple[int, ...]]],
    *,
    progress: bool,
) -> dict[str, Path]:
    """Stream every chunk into one ``(n_frames, ...)`` ``.npy`` per result, each renamed into place when full."""
    n_frames = chunks[-1].stop
    finals = {name: work / f"{name}.npy" for name in specs}
    with contextlib.ExitStack() as stack:
        outputs = {}
        for name, (dtype, shape) in specs.items():
            tmp = stack.enter_context(atomic_path(finals[name]))
            outputs[name] = np.lib.format.open_memmap(tmp, mode="w+", dtype=dtype, shape=(n_frames, *shape))
        for chunk in tqdm(chunks, desc="assembling frames", unit="chunk", disable=not progress, leave=False):
            contents = read_chunk(paths[chunk.index], chunk=chunk)
            for name, output in outputs.items():
                output[chunk.start:chunk.stop] = contents.arrays[name]
        for name in specs:
            outputs.pop(name).flush()  # and drop the map before the rename
    return finals
