"""MDD and PC2 point caches: the spec's bytes, an independent reader, streaming, no partial files."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.io import write_mdd, write_pc2

WRITERS = {"mdd": write_mdd, "pc2": write_pc2}


def _tiny_take() -> np.ndarray:
    """2 frames x 3 vertices of values float32 holds exactly."""
    frame0 = np.array([[0.0, 1.0, -2.0], [0.5, 0.25, 3.0], [-1.5, 8.0, 100.0]], np.float32)
    return np.stack([frame0, frame0 * 2 + 0.125])


def _random_take(n_frames: int = 7, n_vertices: int = 50, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).normal(scale=80.0, size=(n_frames, n_vertices, 3)).astype(np.float32)


def _in_blocks(frames: np.ndarray, sizes: list[int]) -> list[tuple[int, np.ndarray]]:
    starts = np.cumsum([0, *sizes[:-1]])
    return [(int(s), frames[s:s + b]) for s, b in zip(starts, sizes)]


def _write(kind: str, path: Path, blocks: object, frames: np.ndarray, **options: object) -> Path:
    return WRITERS[kind](path, blocks, n_frames=frames.shape[0], n_vertices=frames.shape[1], rate=30.0, **options)


# ----------------------------------------------------------------------------- the spec's bytes


def test_mdd_bytes_follow_the_spec(tmp_path: Path) -> None:
    frames = _tiny_take()
    out = write_mdd(tmp_path / "take.mdd", [(0, frames)], n_frames=2, n_vertices=3, rate=30.0)
    expected = (
        struct.pack(">i", 2)  # frame count
        + struct.pack(">i", 3)  # point count
        + struct.pack(">f", 0 / 30.0) + struct.pack(">f", 1 / 30.0)  # time of each frame, seconds
        + b"".join(struct.pack(">fff", *p) for frame in frames.tolist() for p in frame)
    )
    assert out == tmp_path / "take.mdd"
    assert out.read_bytes() == expected


def test_pc2_bytes_follow_the_spec(tmp_path: Path) -> None:
    frames = _tiny_take()
    out = write_pc2(tmp_path / "take.pc2", [(0, frames)], n_frames=2, n_vertices=3, rate=30.0, start_frame=1)
    expected = (
        b"POINTCACHE2\x00"  # char[12] signature
        + struct.pack("<i", 1)  # file version
        + struct.pack("<i", 3)  # numPoints
        + struct.pack("<f", 1.0)  # startFrame
        + struct.pack("<f", 1.0)  # sampleRate: one sample per frame
        + struct.pack("<i", 2)  # numSamples
        + b"".join(struct.pack("<fff", *p) for frame in frames.tolist() for p in frame)
    )
    assert out.read_bytes() == expected


# ----------------------------------------------------------------------------- independent readers


def _read_mdd(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(times, frames) read as Blender's MOD_meshcache_mdd.cc seeks: header, T times, then frame k at 12 n k."""
    n_frames, n_points = np.fromfile(path, dtype=">i4", count=2)
    times = np.fromfile(path, dtype=">f4", count=n_frames, offset=8)
    frames = [np.fromfile(path, dtype=">f4", count=3 * n_points, offset=8 + 4 * n_frames + 12 * n_points * k)
              for k in range(n_frames)]
    assert path.stat().st_size == 8 + 4 * n_frames + 12 * n_points * n_frames
    return times, np.stack(frames).reshape(n_frames, n_points, 3)


def _read_pc2(path: Path) -> tuple[dict[str, object], np.ndarray]:
    """(header, frames): the 32-byte header as a structured record, then sample k at 32 + 12 n k."""
    header_dtype = np.dtype([("signature", "S12"), ("version", "<i4"), ("points", "<i4"),
                             ("start", "<f4"), ("sampling", "<f4"), ("samples", "<i4")])
    record = np.fromfile(path, dtype=header_dtype, count=1)[0]
    header = {name: record[name] for name in header_dtype.names}
    n, t = int(header["points"]), int(header["samples"])
    assert path.stat().st_size == 32 + 12 * n * t
    frames = np.fromfile(path, dtype="<f4", offset=32).reshape(t, n, 3)
    return header, frames


def test_mdd_round_trip_through_an_independent_reader(tmp_path: Path) -> None:
    frames = _random_take()
    write_mdd(tmp_path / "take.mdd", _in_blocks(frames, [3, 3, 1]), n_frames=7, n_vertices=50, rate=59.94)
    times, read = _read_mdd(tmp_path / "take.mdd")
    np.testing.assert_array_equal(read, frames)
    np.testing.assert_array_equal(times, (np.arange(7) / 59.94).astype(np.float32))


def test_pc2_round_trip_through_an_independent_reader(tmp_path: Path) -> None:
    frames = _random_take()
    write_pc2(tmp_path / "take.pc2", _in_blocks(frames, [2, 5]), n_frames=7, n_vertices=50, rate=24.0,
              start_frame=10)
    header, read = _read_pc2(tmp_path / "take.pc2")
    assert header == {"signature": b"POINTCACHE2", "version": 1, "points": 50, "start": 10.0, "sampling": 1.0,
                      "samples": 7}
    np.testing.assert_array_equal(read, frames)


@pytest.mark.parametrize("kind", ["mdd", "pc2"])
def test_a_streamed_write_equals_one_block(kind: str, tmp_path: Path) -> None:
    frames = _random_take(n_frames=40, n_vertices=30, seed=1)
    one = _write(kind, tmp_path / f"one.{kind}", [(0, frames)], frames).read_bytes()
    sizes = [1, 2, 3, 5, 8, 13, 1, 7]
    assert sum(sizes) == 40
    many = _write(kind, tmp_path / f"many.{kind}", iter(_in_blocks(frames, sizes)), frames,
                  progress=True).read_bytes()
    as_float64 = _write(kind, tmp_path / f"f64.{kind}", [(0, frames.astype(np.float64))], frames).read_bytes()
    assert many == one
    assert as_float64 == one  # float64 blocks go out as the float32 they round to


def test_a_large_block_is_written_in_pieces_without_changing_the_bytes(tmp_path: Path) -> None:
    """Blocks over the writers' 32 MiB write size are split; the file must not change."""
    frames = np.random.default_rng(2).normal(size=(3, 1_000_000, 3)).astype(np.float32)  # 12 MB a frame
    write_pc2(tmp_path / "big.pc2", [(0, frames)], n_frames=3, n_vertices=1_000_000, rate=60.0)
    _, read = _read_pc2(tmp_path / "big.pc2")
    np.testing.assert_array_equal(read, frames)


# ----------------------------------------------------------------------------- errors leave nothing


def _bad_streams() -> dict[str, object]:
    frames = _random_take(n_frames=6, n_vertices=50)
    nan = frames.copy()
    nan[4, 7, 1] = np.nan
    inf = frames.copy()
    inf[1, 0, 2] = -np.inf

    def failing_source():  # the caller's computation fails after two blocks
        yield 0, frames[:2]
        yield 2, frames[2:4]
        raise InputError("the solver gave up")

    return {
        "out of order": [(0, frames[:2]), (4, frames[4:]), (2, frames[2:4])],
        "gap": [(0, frames[:2]), (3, frames[3:])],
        "overlap": [(0, frames[:3]), (2, frames[2:])],
        "wrong vertex count": [(0, frames[:, :49])],
        "2-d block": [(0, frames[0])],
        "empty block": [(0, frames[:0]), (0, frames)],
        "integer positions": [(0, frames.astype(np.int32))],
        "nan": [(0, nan[:3]), (3, nan[3:])],
        "inf": [(0, inf)],
        "beyond float32": [(0, frames.astype(np.float64) * 1e38)],
        "short stream": [(0, frames[:5])],
        "too many frames": [(0, frames), (6, frames[:1])],
        "not a pair": [frames],
        "source fails": failing_source(),
    }


@pytest.mark.parametrize("kind", ["mdd", "pc2"])
@pytest.mark.parametrize("case", sorted(_bad_streams()))
def test_a_bad_stream_raises_and_leaves_nothing(kind: str, case: str, tmp_path: Path) -> None:
    blocks = _bad_streams()[case]
    with pytest.raises(InputError):
        WRITERS[kind](tmp_path / f"take.{kind}", blocks, n_frames=6, n_vertices=50, rate=30.0)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("kind", ["mdd", "pc2"])
def test_a_failed_write_keeps_the_older_file(kind: str, tmp_path: Path) -> None:
    target = tmp_path / f"take.{kind}"
    target.write_bytes(b"older result")
    frames = _random_take(n_frames=6)
    with pytest.raises(InputError, match="ended after 5 of 6"):
        WRITERS[kind](target, [(0, frames[:5])], n_frames=6, n_vertices=50, rate=30.0)
    assert [p.name for p in tmp_path.iterdir()] == [target.name]
    assert target.read_bytes() == b"older result"


@pytest.mark.parametrize("kind", ["mdd", "pc2"])
@pytest.mark.parametrize(
    "options, message",
    [
        ({"n_frames": 0}, "n_frames"),
        ({"n_frames": 2.0}, "n_frames"),
        ({"n_vertices": 2**31}, "n_vertices"),
        ({"rate": 0.0}, "rate"),
        ({"rate": float("nan")}, "rate"),
    ],
)
def test_bad_arguments_are_named(kind: str, options: dict[str, object], message: str, tmp_path: Path) -> None:
    arguments: dict[str, object] = {"n_frames": 2, "n_vertices": 3, "rate": 30.0, **options}
    with pytest.raises(InputError, match=message):
        WRITERS[kind](tmp_path / f"take.{kind}", [(0, _tiny_take())], **arguments)
    assert list(tmp_path.iterdir()) == []


def test_bad_destinations_and_start_frame_are_refused(tmp_path: Path) -> None:
    frames = _tiny_take()
    with pytest.raises(InputError, match=r"\.mdd file name"):
        write_mdd(tmp_path / "take.pc2", [(0, frames)], n_frames=2, n_vertices=3, rate=30.0)
    with pytest.raises(InputError, match=r"\.pc2 file name"):
        write_pc2(tmp_path / "take.mdd", [(0, frames)], n_frames=2, n_vertices=3, rate=30.0)
    with pytest.raises(InputError, match="does not exist"):
        write_mdd(tmp_path / "missing" / "take.mdd", [(0, frames)], n_frames=2, n_vertices=3, rate=30.0)
    with pytest.raises(InputError, match="start_frame"):
        write_pc2(tmp_path / "take.pc2", [(0, frames)], n_frames=2, n_vertices=3, rate=30.0, start_frame=np.inf)
    assert list(tmp_path.iterdir()) == []
