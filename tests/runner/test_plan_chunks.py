"""Chunks cover every frame once, in order; segments chain the chunks they hold and no others."""

from __future__ import annotations

import pytest

from facecap import InputError
from facecap.runner import FrameChunk, plan_chunks


@pytest.mark.parametrize("n_frames", [1, 7, 32, 33, 100])
@pytest.mark.parametrize("chunk_frames", [1, 5, 32])
def test_chunks_cover_every_frame_exactly_once(n_frames: int, chunk_frames: int) -> None:
    chunks = plan_chunks(n_frames, chunk_frames=chunk_frames)
    frames = [f for chunk in chunks for f in range(chunk.start, chunk.stop)]
    assert frames == list(range(n_frames))
    assert [c.index for c in chunks] == list(range(len(chunks)))
    assert all(0 < c.stop - c.start <= chunk_frames for c in chunks)
    assert all(c.previous is None and c.segment == c.index for c in chunks)  # default: every chunk cold


def test_segments_chain_their_chunks() -> None:
    chunks = plan_chunks(50, chunk_frames=10, segment_chunks=2)
    assert chunks == [
        FrameChunk(0, 0, 10, 0, None),
        FrameChunk(1, 10, 20, 0, 0),
        FrameChunk(2, 20, 30, 1, None),
        FrameChunk(3, 30, 40, 1, 2),
        FrameChunk(4, 40, 50, 2, None),
    ]
    one_chain = plan_chunks(30, chunk_frames=10, segment_chunks=None)
    assert [(c.segment, c.previous) for c in one_chain] == [(0, None), (0, 0), (0, 1)]


@pytest.mark.parametrize(
    "arguments",
    [{"n_frames": 0}, {"n_frames": -3}, {"n_frames": 2.0}, {"n_frames": True}, {"chunk_frames": 0},
     {"chunk_frames": "8"}, {"segment_chunks": 0}],
)
def test_counts_must_be_positive_integers(arguments: dict) -> None:
    options = {"n_frames": 10, **arguments}
    name = next(iter(arguments))
    with pytest.raises(InputError, match=f"{name}: expected an integer >= 1"):
        plan_chunks(options.pop("n_frames"), **options)
