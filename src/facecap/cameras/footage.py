"""One camera's footage, read lazily: an image sequence (PNG, JPEG, 16-bit PNG, TIFF, EXR) or a video file (PyAV).

Frames come as stored (see :mod:`facecap.io.image_file`): ``(H, W)`` or
``(H, W, 3)`` RGB arrays of ``uint8``, ``uint16`` or ``float32``, nothing
decoded or rescaled; :func:`~facecap.cameras.image_to_float` and
:func:`~facecap.cameras.srgb_to_linear` convert.

Video is decoded by PyAV (FFmpeg's libraries): whatever FFmpeg decodes, among
them H.264, H.265, ProRes, DNxHD, MJPEG, VP9, FFV1, PNG and QuickTime RLE in
MP4, MOV, MKV or AVI; 8-bit sources give ``uint8`` RGB, sources with more bits
per component give ``uint16`` RGB, grey sources a 2D array. The decoder's own
YUV -> RGB conversion (FFmpeg's swscale, BT.601 unless the stream says
otherwise, and the range the stream is tagged with: limited when untagged) is used as is.
"""

from __future__ import annotations

import glob
import os
import re
from collections.abc import Iterator
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FileFormatError, InputError
from ..io.image_file import IMAGE_SUFFIXES, read_image

__all__ = ["Footage", "open_footage", "VIDEO_SUFFIXES"]

VIDEO_SUFFIXES = (".mp4", ".mov", ".mkv", ".avi", ".m4v", ".webm", ".mxf")
"""Video container suffixes :func:`open_footage` opens with PyAV (lower case)."""

_SEEK_AHEAD_FRAMES = 32  # decoding forward beats a seek for short jumps
_NUMBER = re.compile(r"(\d+)(?!.*\d)")  # the last run of digits in a file name


class Footage:
    """Frames of one camera, from an image sequence or a video file; open with :func:`open_footage`.

    Attributes
    ----------
    path : pathlib.Path
        The folder, pattern's folder or video file.
    kind : {'images', 'video'}
    n_frames : int
    width, height : int
    channels : int
        1 (grey), 3 (RGB) or 4 (RGBA, image sequences only).
    dtype : numpy.dtype
        ``uint8``, ``uint16`` or ``float32``.
    rate_hz : float or None
        The video's frame rate (its average rate); None for image sequences,
        which state none (the camera file does: ``footage.rate_hz``).
    files : tuple of pathlib.Path
        The image files in frame order (empty for video).
    first_number : int or None
        The number in the first image's name (frame 0 of the footage).

    Notes
    -----
    Use it as a context manager, or call :meth:`close`, to release a video
    file. Reading frames in order is fastest; a backward or long forward jump
    in a video seeks to the previous key frame and decodes forward.
    """

    def __init__(self, path: Path, kind: str, files: tuple[Path, ...] = (), first_number: int | None = None) -> None:
        self.path = path
        self.kind = kind
        self.files = files
        self.first_number = first_number
        self.rate_hz: float | None = None
        self._container: Any = None
        self._decoder: Iterator[Any] | None = None
        self._next_index = 0
        if kind == "images":
            first = read_image(files[0])
            self.n_frames = len(files)
            self._set_layout(first)
        else:
            self._open_video()

    # -- layout ---------------------------------------------------------------------------------

    def _set_layout(self, frame: np.ndarray) -> None:
        self.height, self.width = int(frame.shape[0]), int(frame.shape[1])
        self.channels = 1 if frame.ndim == 2 else int(frame.shape[2])
        self.dtype = frame.dtype

    def _check_layout(self, frame: np.ndarray, index: int, where: Path) -> np.ndarray:
        channels = 1 if frame.ndim == 2 else frame.shape[2]
        if frame.shape[:2] != (self.height, self.width) or channels != self.channels or frame.dtype != self.dtype:
            raise FileFormatError(
                f"frame {index} is {frame.shape[1]}x{frame.shape[0]}x{channels} {frame.dtype}, frame 0 is "
                f"{self.width}x{self.height}x{self.channels} {self.dtype}: every frame of a sequence must match",
                path=str(where),
            )
        return frame

    # -- video ----------------------------------------------------------------------------------

    def _open_video(self) -> None:
        import av

        try:
            container = av.open(str(self.path))
        except (av.error.FFmpegError, OSError) as exc:
            raise FileFormatError(f"FFmpeg cannot open it as a video ({exc})", path=str(self.path)) from None
        if not container.streams.video:
            container.close()
            raise FileFormatError("the file holds no video stream", path=str(self.path))
        stream = container.streams.video[0]
        codec = stream.codec_context
        fmt = codec.format
        if fmt is None or not codec.width:
            container.close()
            raise FileFormatError("the video stream has no decodable picture format", path=str(self.path))
        bits = max(c.bits for c in fmt.components)
        grey = len(fmt.components) == 1 or fmt.name.startswith("gray")
        if grey:
            self._pixel_format = "gray16le" if bits > 8 else "gray"
        else:
            self._pixel_format = "rgb48le" if bits > 8 else "rgb24"
        self.width, self.height = int(codec.width), int(codec.height)
        self.channels = 1 if grey else 3
        self.dtype = np.dtype(np.uint16 if bits > 8 else np.uint8)
        rate = stream.average_rate or stream.guessed_rate
        self._rate = Fraction(rate) if rate else None
        self.rate_hz = float(rate) if rate else None
        self._time_base = Fraction(stream.time_base) if stream.time_base else None
        self._start = stream.start_time or 0
        n_frames = int(stream.frames or 0)
        if n_frames <= 0:  # MKV and some others store no count: count the packets (no decoding)
            n_frames = sum(1 for packet in container.demux(stream) if packet.size > 0)
            container.seek(0)
        self.n_frames = n_frames
        self._container = container
        self._stream = stream
        self._restart()

    def _restart(self) -> None:
        self._container.seek(self._start if self._start else 0, stream=self._stream, backward=True)
        self._decoder = self._container.decode(self._stream)
        self._next_index = 0
        self._exact_index = True

    def _index_of(self, frame: Any) -> int | None:
        if frame.pts is None or self._time_base is None or self._rate is None:
            return None
        return int(round((frame.pts - self._start) * self._time_base * self._rate))

    def _convert(self, frame: Any) -> np.ndarray:
        # the stream's own range tag (full-range "yuvj" video), else swscale's default (limited range)
        tagged = getattr(frame, "color_range", 0)
        options = {"src_color_range": tagged} if tagged else {}
        return np.ascontiguousarray(frame.to_ndarray(format=self._pixel_format, **options))

    def _video_frame(self, index: int) -> np.ndarray:
        import av

        jump = index - self._next_index
        if jump < 0 or jump > _SEEK_AHEAD_FRAMES:
            self._seek(index)
        try:
            while True:
                frame = next(self._decoder)  # type: ignore[arg-type]
                if not self._exact_index:  # after a seek: the frame's number from its time stamp
                    found = self._index_of(frame)
                    if found is None or found > index:  # irregular time stamps: decode from the start instead
                        self._restart()
                        return self._video_frame(index)
                    self._next_index = found
                    self._exact_index = True
                current = self._next_index
                self._next_index += 1
                if current == index:
                    return self._convert(frame)
        except StopIteration:
            self._restart()
            raise FileFormatError(f"the video ends before frame {index} (it said {self.n_frames} frames)",
                                  path=str(self.path)) from None
        except av.error.FFmpegError as exc:
            self._restart()
            raise FileFormatError(f"cannot decode frame {index} ({exc})", path=str(self.path)) from None

    def _seek(self, index: int) -> None:
        if index == 0 or self._time_base is None or self._rate is None:
            self._restart()
            return
        target = self._start + int(Fraction(index) / self._rate / self._time_base)
        self._container.seek(target, stream=self._stream, backward=True, any_frame=False)
        self._decoder = self._container.decode(self._stream)
        self._exact_index = False

    # -- public ---------------------------------------------------------------------------------

    def __len__(self) -> int:
        return self.n_frames

    def frame(self, index: int) -> np.ndarray:
        """Frame ``index`` (0-based; negative counts from the end) as stored.

        Raises
        ------
        InputError
            If ``index`` is out of range.
        FileFormatError
            If the frame cannot be read, or differs in size or type from frame 0.
        """
        if isinstance(index, (bool, np.bool_)) or not isinstance(index, (int, np.integer)):
            raise InputError(f"frame index: expected an integer, got {index!r}")
        i = int(index) + (self.n_frames if index < 0 else 0)
        if not 0 <= i < self.n_frames:
            raise InputError(f"frame {index} out of range: the footage has {self.n_frames} frames", path=str(self.path))
        if self.kind == "images":
            return self._check_layout(read_image(self.files[i]), i, self.files[i])
        if self._container is None:
            raise InputError("the footage is closed", path=str(self.path))
        return self._video_frame(i)

    __getitem__ = frame

    def __iter__(self) -> Iterator[np.ndarray]:
        for i in range(self.n_frames):
            yield self.frame(i)

    def frames(self, start: int = 0, stop: int | None = None) -> Iterator[np.ndarray]:
        """Frames ``start <= i < stop`` in order (stop default: the end)."""
        stop = self.n_frames if stop is None else min(int(stop), self.n_frames)
        for i in range(int(start), stop):
            yield self.frame(i)

    def check_camera(self, camera: Any) -> None:
        """Raise unless the footage's frame size is the camera's calibrated image size.

        Parameters
        ----------
        camera : Camera

        Raises
        ------
        InputError
            Naming both sizes; when the footage is the calibration scaled
            uniformly (a proxy or a downscaled export), says so.
        """
        if (self.width, self.height) == (camera.width, camera.height):
            return
        hint = ""
        scale_x, scale_y = self.width / camera.width, self.height / camera.height
        if abs(scale_x - scale_y) < 1e-3:
            hint = f" (the footage is the calibrated size scaled by {scale_x:g}: calibrate at its size or scale K)"
        elif (self.width, self.height) == (camera.height, camera.width):
            hint = " (width and height are swapped: rotated footage?)"
        raise InputError(
            f"footage is {self.width}x{self.height} but camera {camera.name!r} is calibrated for "
            f"{camera.width}x{camera.height}{hint}",
            path=str(self.path),
        )

    def close(self) -> None:
        """Release the video file (nothing to do for an image sequence)."""
        if self._container is not None:
            self._container.close()
            self._container = None

    def __enter__(self) -> "Footage":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        rate = f", {self.rate_hz:g} Hz" if self.rate_hz else ""
        return (f"Footage({str(self.path)!r}, {self.kind}, {self.n_frames} frames, {self.width}x{self.height}x"
                f"{self.channels} {self.dtype}{rate})")


def _numbered(files: list[Path], where: str) -> tuple[tuple[Path, ...], int]:
    """Files sorted by the last number in their names, which must run without a gap."""
    numbered = []
    for f in files:
        match = _NUMBER.search(f.stem)
        if match is None:
            raise FileFormatError(f"image {f.name!r} has no frame number in its name", path=where)
        numbered.append((int(match.group(1)), f))
    numbered.sort()
    numbers = [n for n, _ in numbered]
    repeated = sorted({n for n in numbers if numbers.count(n) > 1})
    if repeated:
        raise FileFormatError(f"frame numbers {repeated[:5]} appear more than once", path=where)
    expected = set(range(numbers[0], numbers[-1] + 1))
    missing = sorted(expected - set(numbers))
    if missing:
        raise FileFormatError(f"frames missing from the sequence: {missing[:10]}{' ...' if len(missing) > 10 else ''} "
                              f"(numbers {numbers[0]}..{numbers[-1]}); a gap would shift every later frame",
                              path=where)
    return tuple(f for _, f in numbered), numbers[0]


def open_footage(path: str | os.PathLike[str]) -> Footage:
    """Open one camera's footage.

    Parameters
    ----------
    path : str or path-like
        One of:

        - a folder of numbered images (``frame_000000.png`` ...), all of one suffix;
        - a glob pattern (``cam0/*.exr``);
        - a printf pattern (``cam0/frame_%06d.png``);
        - a video file (``.mp4``, ``.mov``, ``.mkv``, ``.avi``, ``.m4v``, ``.webm``, ``.mxf``);
        - a single image (a one-frame sequence).

        Images are ordered by the last number in their names, which must run
        without a gap (frame 0 is the lowest number).

    Returns
    -------
    Footage

    Raises
    ------
    FileFormatError
        If nothing matches, the folder mixes image types, numbers repeat or
        skip, or the file cannot be opened; the message names the path.

    Examples
    --------
    >>> import numpy as np, pathlib, tempfile
    >>> from facecap.cameras import write_image_sequence
    >>> folder = pathlib.Path(tempfile.mkdtemp()) / "cam0"
    >>> write_image_sequence(folder, np.zeros((3, 4, 5, 3), dtype=np.uint8))
    >>> with open_footage(folder) as footage:
    ...     footage.n_frames, footage.frame(2).shape
    (3, (4, 5, 3))
    """
    text = os.fspath(path)
    file = Path(text)
    if file.is_dir():
        images = [f for f in file.iterdir() if f.is_file() and f.suffix.lower() in IMAGE_SUFFIXES
                  and not f.name.startswith(".")]
        if not images:
            raise FileFormatError(f"the folder holds no image ({', '.join(IMAGE_SUFFIXES)})", path=text)
        suffixes = sorted({f.suffix.lower() for f in images})
        if len(suffixes) > 1:
            raise FileFormatError(f"the folder mixes image types {suffixes}; give a pattern such as "
                                  f"'{file / ('*' + suffixes[0])}'", path=text)
        files, first = _numbered(images, text)
        return Footage(file, "images", files, first)
    if "%" in file.name:
        try:
            first_name = file.name % 0
        except (TypeError, ValueError):
            raise FileFormatError("not a printf frame pattern (expected one %d, e.g. frame_%06d.png)",
                                  path=text) from None
        start = 0 if (file.parent / first_name).is_file() else 1
        files_list = []
        while (file.parent / (file.name % (start + len(files_list)))).is_file():
            files_list.append(file.parent / (file.name % (start + len(files_list))))
        if not files_list:
            raise FileFormatError("no image matches the pattern (tried frame 0 and 1)", path=text)
        return Footage(file.parent, "images", tuple(files_list), start)
    if any(c in file.name for c in "*?["):
        matches = [Path(m) for m in glob.glob(text) if Path(m).is_file()]
        matches = [m for m in matches if m.suffix.lower() in IMAGE_SUFFIXES]
        if not matches:
            raise FileFormatError("no image file matches the pattern", path=text)
        files, first = _numbered(matches, text)
        return Footage(file.parent, "images", files, first)
    if not file.exists():
        raise FileFormatError("footage not found", path=text)
    suffix = file.suffix.lower()
    if suffix in VIDEO_SUFFIXES:
        return Footage(file, "video")
    if suffix in IMAGE_SUFFIXES:
        return Footage(file.parent, "images", (file,), None)
    raise FileFormatError(f"not footage facecap reads: expected a folder or pattern of {IMAGE_SUFFIXES} "
                          f"images or a video file {VIDEO_SUFFIXES}", path=text)
