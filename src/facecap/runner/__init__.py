"""The frame runner: slow per-frame stages over every frame of a take, in resumable chunks on Dask.

One home for running a stage that costs seconds per frame (the wrinkle layer, the
muscle solve); see ``docs/runner.md``. In the order a user meets them:

- :func:`run_frames`, :class:`FrameRun` (``run_frames.py``): the runner; chunks as
  Dask tasks on a local cluster, an existing one (``scheduler='tcp://…'``) or in
  this process (``'synchronous'``), resumed from the work folder's finished chunks.
- :class:`FrameStage`, :func:`stage_identity` (``frame_stage.py``): the contract a
  stage fulfils, ``stage(start, stop, state) -> (arrays, state)``, and what the
  run's manifest records of it.
- :func:`plan_chunks`, :class:`FrameChunk` (``plan_chunks.py``): frames cut into
  chunks, and chunks grouped into warm-started segments.
- :func:`run_chunk`, :func:`read_chunk`, :class:`ChunkContents` (``run_chunk.py``):
  one chunk computed and written atomically (the file is its own done-marker),
  and read back.
- :func:`connect_scheduler` (``connect_scheduler.py``): the Dask client for a
  scheduler argument (``--scheduler ADDRESS`` on the command line).

Dask itself is imported only when a cluster is used.
"""

from __future__ import annotations

from .connect_scheduler import SYNCHRONOUS, connect_scheduler
from .frame_stage import FrameStage, StageState, stage_identity
from .plan_chunks import FrameChunk, plan_chunks
from .run_chunk import CHUNK_FORMAT, ChunkContents, chunk_file_name, read_chunk, run_chunk
from .run_frames import MANIFEST_FILE, MANIFEST_FORMAT, FrameRun, run_frames

__all__ = [
    "run_frames",
    "FrameRun",
    "MANIFEST_FILE",
    "MANIFEST_FORMAT",
    "FrameStage",
    "StageState",
    "stage_identity",
    "plan_chunks",
    "FrameChunk",
    "run_chunk",
    "read_chunk",
    "chunk_file_name",
    "ChunkContents",
    "CHUNK_FORMAT",
    "connect_scheduler",
    "SYNCHRONOUS",
]
