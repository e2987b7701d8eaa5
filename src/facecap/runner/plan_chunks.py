"""How a run of frames is cut into chunks (the unit of work and of resume) and segments."""

from __future__ import annotations

from typing import NamedTuple

from ..validate import as_count

__all__ = ["FrameChunk", "plan_chunks"]


class FrameChunk(NamedTuple):
    """One chunk of frames: a Dask task, one file, the unit of resume.

    Attributes
    ----------
    index : int
        Position in the run, 0-based.
    start, stop : int
        Frames ``start <= frame < stop``.
    segment : int
        The segment the chunk belongs to: state flows from chunk to chunk within a
        segment, never across segments.
    previous : int or None
        Index of the chunk whose returned state this chunk starts from; None for
        the first chunk of a segment (which starts cold, from state None).
    """

    index: int
    start: int
    stop: int
    segment: int
    previous: int | None


def plan_chunks(n_frames: int, *, chunk_frames: int = 32, segment_chunks: int | None = 1) -> list[FrameChunk]:
    """Cut frames ``0 .. n_frames - 1`` into chunks, grouped into warm-started segments.

    Parameters
    ----------
    n_frames : int
        Number of frames of the run, at least 1.
    chunk_frames : int, optional
        Frames per chunk, default 32 (the last chunk may be shorter). A chunk is
        the unit of work sent to a worker, of progress, and of what a resume can
        skip: choose it so that a chunk takes tens of seconds to minutes.
    segment_chunks : int or None, optional
        Chunks per segment, default 1: every chunk starts cold (state None) and
        all chunks may run at once. ``k > 1``: the state returned by a chunk is
        handed to the next chunk of its segment, which therefore runs after it;
        segments of ``k`` chunks run in parallel. None: the whole run is one
        segment (an exact frame-to-frame chain, one chunk at a time).

    Returns
    -------
    chunks : list of FrameChunk
        In frame order, covering every frame exactly once.

    Raises
    ------
    InputError
        If a count is not a positive integer.

    Examples
    --------
    >>> [c[:3] for c in plan_chunks(70, chunk_frames=32)]
    [(0, 0, 32), (1, 32, 64), (2, 64, 70)]
    >>> [(c.segment, c.previous) for c in plan_chunks(70, chunk_frames=32, segment_chunks=2)]
    [(0, None), (0, 0), (1, None)]
    """
    n_frames = as_count(n_frames, name="n_frames")
    chunk_frames = as_count(chunk_frames, name="chunk_frames")
    if segment_chunks is not None:
        segment_chunks = as_count(segment_chunks, name="segment_chunks")
    chunks = []
    for index, start in enumerate(range(0, n_frames, chunk_frames)):
        segment = 0 if segment_chunks is None else index // segment_chunks
        first_of_segment = index == 0 or (segment_chunks is not None and index % segment_chunks == 0)
        chunks.append(FrameChunk(index, start, min(start + chunk_frames, n_frames), segment,
                                 None if first_of_segment else index - 1))
    return chunks
