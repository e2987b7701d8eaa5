"""The checks the streamed writers share: each bad stream, count or name is refused in one line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.io.frame_blocks import as_frame_count, check_frame_blocks, path_with_suffix


def _blocks(*sizes: int, n: int = 4, start: int = 0):
    for b in sizes:
        yield start, np.zeros((b, n, 3), np.float32)
        start += b


def test_a_good_stream_passes_unchanged() -> None:
    blocks = list(_blocks(2, 3))
    out = list(check_frame_blocks(iter(blocks), n_frames=5, n_vertices=4, path=Path("a.mdd")))
    assert [s for s, _ in out] == [0, 2] and all(a is b for (_, a), (_, b) in zip(out, blocks))


@pytest.mark.parametrize(("blocks", "message"), [
    (list(_blocks(2, 2)), "ended after 4 of 5"),
    (list(_blocks(3, 3)), "run past n_frames=5"),
    ([(1, np.zeros((5, 4, 3), np.float32))], "starting at frame 0"),
    ([(0, np.zeros((5, 3, 3), np.float32))], r"\(b, 4, 3\)"),
    ([(0, np.full((5, 4, 3), np.nan, np.float32))], "frame 0 contains NaN"),
    ([(0, np.full((5, 4, 3), 1e300))], "float32 range"),
    ([(0, np.zeros((5, 4, 3), np.int32))], "float32 positions"),
])
def test_a_bad_stream_is_refused(blocks, message) -> None:
    with pytest.raises(InputError, match=message):
        list(check_frame_blocks(blocks, n_frames=5, n_vertices=4, path=Path("a.mdd")))


def test_counts_and_names() -> None:
    assert as_frame_count(np.int64(7), name="n_frames") == 7
    for bad in (0, True, 2**31, 1.0):
        with pytest.raises(InputError, match="n_frames"):
            as_frame_count(bad, name="n_frames")
    assert path_with_suffix("take.MDD", ".mdd") == Path("take.MDD")
    with pytest.raises(InputError, match=r"\.pc2 file name"):
        path_with_suffix("take.mdd", ".pc2")
