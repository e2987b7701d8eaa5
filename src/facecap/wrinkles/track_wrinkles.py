"""Wrinkle tracking in one camera's footage (Bickel et al. 2007, section 5.1): paint -> patches -> valley splines.

Each frame: the paint classifier labels the pixels, a morphological clean-up removes stray
pixels, the connected patches of each colour are matched to the wrinkles of the previous frame
by overlap (the first frame's come from the painted mask), and each wrinkle's pixels get the
weighted B-spline of eq. 5 along their principal axis.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any, Iterable, Iterator

import numpy as np

from ..errors import FacecapWarning, InputError
from ..typing import FloatArray, IntArray
from .wrinkle_masks import PaintClassifier, classify_paint, clean_paint_labels, train_paint_classifier
from .wrinkle_splines import WrinkleSpline, darkness_weights, fit_wrinkle_spline

__all__ = ["TrackedWrinkle", "WrinkleTracker", "WrinkleTrackingWarning", "track_wrinkles"]


class WrinkleTrackingWarning(FacecapWarning):
    """A wrinkle was lost, or reaches the image border (part of it may be outside the image)."""


@dataclass(frozen=True)
class TrackedWrinkle:
    """One wrinkle in one frame of one camera.

    Attributes
    ----------
    wrinkle : int
        Its identity, the same in every frame (numbered from the first frame's mask: by paint,
        then left to right).
    color : int
        Index of its paint (the classifier's colour ``i``; mask value ``1 + i``).
    spline : WrinkleSpline
        The valley curve (eq. 5), in pixels.
    n_pixels : int
        Pixels in its patch.
    at_border : bool
        The patch reaches the image border: the wrinkle may continue outside the image, and its
        curve covers only the visible part.
    """

    wrinkle: int
    color: int
    spline: WrinkleSpline
    n_pixels: int
    at_border: bool

    def curve(self, n: int = 64, *, trim_caps: bool = True) -> FloatArray:
        """``n`` points along the valley (px). ``trim_caps`` leaves out the stripe's half-width at each
        end: paint covers the bulges around the valley's ends as well as beside it."""
        return self.spline.sample(n, trim=self.spline.half_width if trim_caps else 0.0)


def _components(labels: IntArray, n_colors: int, min_area_px: int) -> tuple[IntArray, IntArray]:
    """Connected patches of every colour: (H, W) patch index (-1 none), and each patch's colour."""
    import cv2

    patches = np.full(labels.shape, -1, dtype=np.int64)
    colors: list[int] = []
    for i in range(n_colors):
        count, comp, stats, _ = cv2.connectedComponentsWithStats((labels == i + 1).astype(np.uint8), connectivity=8)
        keep = np.flatnonzero(stats[1:, cv2.CC_STAT_AREA] >= min_area_px) + 1
        if keep.size == 0:
            continue
        remap = np.full(count, -1, dtype=np.int64)
        remap[keep] = len(colors) + np.arange(keep.size)
        inside = comp > 0
        patches[inside] = np.where(remap[comp[inside]] >= 0, remap[comp[inside]], patches[inside])
        colors.extend([i] * keep.size)
    return patches, np.asarray(colors, dtype=np.int64)


class WrinkleTracker:
    """Follow the painted wrinkles of one camera from frame to frame.

    Parameters
    ----------
    classifier : PaintClassifier
        Trained on the first frame; its ``mask_labels`` define the wrinkles.
    camera : str, default ''
        The camera's name, for warnings.
    min_area_px : int, default 40
        Patches smaller than this are noise, not wrinkles.
    opening_px, closing_px : int, default 1 and 2
        The clean-up (:func:`~facecap.wrinkles.clean_paint_labels`).
    weighting : {'uniform', 'darkness'}, default 'uniform'
        Eq. 5's weights: equal, or the paper's, inversely proportional to grey level
        (:func:`~facecap.wrinkles.darkness_weights`: the valley is darker than its bulges).
        Measured on generated footage (``benchmarks/bench_track_wrinkles.py``, seed 0): mean
        distance to the true valleys 0.70 / 0.66 px (two cameras) uniform, 1.24 / 1.13 px with the
        paper's weights: the face's own shading across a stripe outweighs the valley's darkening
        and pulls the curve sideways, while the stripe is painted symmetric about the valley.
    border_px : int, default 2
        A patch within this many pixels of the image edge is flagged ``at_border``.
    spacing_px : float, default 30.0
        Control-point spacing along the wrinkle (5-12 points).

    Raises
    ------
    InputError
        If the mask holds no patch of at least ``min_area_px`` pixels.
    """

    def __init__(self, classifier: PaintClassifier, *, camera: str = "", min_area_px: int = 40, opening_px: int = 1,
                 closing_px: int = 2, weighting: str = "uniform", border_px: int = 2, spacing_px: float = 30.0) -> None:
        if weighting not in ("darkness", "uniform"):
            raise InputError(f"weighting: expected 'darkness' or 'uniform', got {weighting!r}")
        self.classifier = classifier
        self.camera = camera
        self.min_area_px = int(min_area_px)
        self.opening_px, self.closing_px = int(opening_px), int(closing_px)
        self.weighting = weighting
        self.border_px = int(border_px)
        self.spacing_px = float(spacing_px)
        labels = clean_paint_labels(classifier.mask_labels, classifier.n_colors, opening_px=opening_px,
                                    closing_px=closing_px)
        patches, colors = _components(labels, classifier.n_colors, self.min_area_px)
        if colors.size == 0:
            raise InputError(f"mask{self._where()}: no painted patch of {self.min_area_px} pixels or more")
        # number the wrinkles by paint, then left to right (by mean column)
        cols = np.bincount(patches[patches >= 0], weights=np.nonzero(patches >= 0)[1], minlength=colors.size)
        mean_col = cols / np.bincount(patches[patches >= 0], minlength=colors.size)
        order = np.lexsort((mean_col, colors))
        rank = np.empty(colors.size, dtype=np.int64)
        rank[order] = np.arange(colors.size)
        self.wrinkle_colors = colors[order]
        self._reference = np.where(patches >= 0, rank[np.maximum(patches, 0)], -1)
        self._lost: set[int] = set()
        self._warned_border: set[int] = set()
        self._frame = 0

    @property
    def n_wrinkles(self) -> int:
        return int(self.wrinkle_colors.size)

    def _where(self) -> str:
        return f" (camera {self.camera})" if self.camera else ""

    def track(self, image: Any) -> list[TrackedWrinkle]:
        """The wrinkles in the next frame, in wrinkle order (a lost wrinkle is left out, with a warning).

        Parameters
        ----------
        image : (H, W, 3) array
            RGB, the size of the mask.

        Returns
        -------
        list of TrackedWrinkle
        """
        from ..cameras.image_to_float import image_to_float

        A = np.asarray(image)
        if A.shape[:2] != self._reference.shape:
            raise InputError(f"frame {self._frame}{self._where()}: image size {A.shape[:2]} differs from the "
                             f"mask's {self._reference.shape}")
        labels = clean_paint_labels(classify_paint(self.classifier, A), self.classifier.n_colors,
                                    opening_px=self.opening_px, closing_px=self.closing_px)
        patches, colors = _components(labels, self.classifier.n_colors, self.min_area_px)
        n_w = self.n_wrinkles
        found = patches >= 0
        rows, cols = np.nonzero(found)
        patch_of = patches[rows, cols]
        previous = self._reference[rows, cols]
        # overlap counts (patch, wrinkle of the same paint): each patch joins the wrinkle it overlaps most
        same = (previous >= 0) & (self.wrinkle_colors[np.maximum(previous, 0)] == colors[patch_of])
        overlap = np.bincount(patch_of[same] * n_w + previous[same], minlength=colors.size * n_w).reshape(-1, n_w)
        owner = np.where(overlap.max(axis=1) > 0, overlap.argmax(axis=1), -1)
        wrinkle_of_pixel = owner[patch_of]
        reference = np.full(self._reference.shape, -1, dtype=np.int64)
        reference[rows, cols] = wrinkle_of_pixel

        gray = None
        if self.weighting == "darkness":
            gray = image_to_float(A)[..., :3].mean(axis=-1)
        H, W = self._reference.shape
        b = self.border_px
        result: list[TrackedWrinkle] = []
        assigned = wrinkle_of_pixel >= 0
        order = np.argsort(wrinkle_of_pixel[assigned], kind="stable")
        r_sorted, c_sorted = rows[assigned][order], cols[assigned][order]
        counts = np.bincount(wrinkle_of_pixel[assigned], minlength=n_w)
        starts = np.concatenate([[0], np.cumsum(counts)])
        for k in range(n_w):
            if counts[k] < max(self.min_area_px, 8):
                if k not in self._lost:
                    self._lost.add(k)
                    warnings.warn(f"frame {self._frame}{self._where()}: wrinkle {k} (paint {self.wrinkle_colors[k]}) "
                                  "was not found; it is left out until it reappears where it was last seen",
                                  WrinkleTrackingWarning, stacklevel=2)
                reference[(self._reference == k) & (reference < 0)] = k  # look for it where it was last seen
                continue
            self._lost.discard(k)
            r = r_sorted[starts[k]:starts[k + 1]]
            c = c_sorted[starts[k]:starts[k + 1]]
            pixels = np.stack([c, r], axis=1).astype(np.float64)
            weights = None if gray is None else darkness_weights(gray[r, c])
            spline = fit_wrinkle_spline(pixels, weights, spacing_px=self.spacing_px)
            at_border = bool(r.min() < b or c.min() < b or r.max() >= H - b or c.max() >= W - b)
            if at_border and k not in self._warned_border:
                self._warned_border.add(k)
                warnings.warn(f"frame {self._frame}{self._where()}: wrinkle {k} (paint {self.wrinkle_colors[k]}) "
                              "reaches the image border: it may leave the image, and its curve covers only the "
                              "visible part (flagged at_border)", WrinkleTrackingWarning, stacklevel=2)
            result.append(TrackedWrinkle(wrinkle=k, color=int(self.wrinkle_colors[k]), spline=spline,
                                         n_pixels=int(r.size), at_border=at_border))
        self._reference = reference
        self._frame += 1
        return result


def _frames(footage: Any, start: int, stop: int | None) -> Iterator[Any]:
    if hasattr(footage, "frames") and hasattr(footage, "frame"):
        yield from footage.frames(start, stop)
        return
    for i, image in enumerate(footage):
        if i < start:
            continue
        if stop is not None and i >= stop:
            return
        yield image


def track_wrinkles(footage: Any, mask: Any, *, n_colors: int | None = None, classifier: PaintClassifier | None = None,
                   camera: str = "", start: int = 0, stop: int | None = None, progress: bool = False,
                   **tracker_options: Any) -> list[list[TrackedWrinkle]]:
    """Track the painted wrinkles through one camera's footage.

    Parameters
    ----------
    footage : facecap.cameras.Footage or iterable of (H, W, 3) arrays
        The camera's frames, RGB (:func:`~facecap.cameras.open_footage`); frame ``start``
        is the one the mask was painted on.
    mask : (H, W) array or sequence of (H, W) arrays
        The first frame's paint mask, in any form :func:`~facecap.wrinkles.train_paint_classifier`
        takes (labels, one binary mask for every paint, or one per paint).
    n_colors : int, optional
        For a binary mask: how many paints (chosen automatically if not given).
    classifier : PaintClassifier, optional
        Already trained (``mask`` is then ignored).
    camera : str, default ''
        Its name, for messages.
    start, stop : int, default 0 and None
        The frames to track.
    progress : bool, default False
        Show a tqdm progress bar.
    **tracker_options
        Passed to :class:`WrinkleTracker`.

    Returns
    -------
    list of list of TrackedWrinkle
        Per frame, the wrinkles found (in wrinkle order).

    Raises
    ------
    InputError
        If the mask does not match the frames, a paint colour has no pixel in it, or the
        footage is empty.

    Warns
    -----
    WrinkleTrackingWarning
        When a wrinkle is lost, or reaches the image border (the wrinkle is flagged ``at_border``).

    Examples
    --------
    >>> from facecap.cameras import open_footage  # doctest: +SKIP
    >>> tracks = track_wrinkles(open_footage("case/cam_left"), read_image("case/mask_cam_left.png"))  # doctest: +SKIP
    """
    frames = _frames(footage, start, stop)
    try:
        first = next(frames)
    except StopIteration:
        raise InputError(f"footage{' of camera ' + camera if camera else ''}: no frame to track") from None
    if classifier is None:
        classifier = train_paint_classifier(first, mask, n_colors=n_colors)
    tracker = WrinkleTracker(classifier, camera=camera, **tracker_options)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(desc=f"tracking {camera}".strip(), unit="frame")
    tracks = []
    for image in _chain(first, frames):
        tracks.append(tracker.track(image))
        if bar is not None:
            bar.update()
    if bar is not None:
        bar.close()
    return tracks


def _chain(first: Any, rest: Iterable[Any]) -> Iterator[Any]:
    yield first
    yield from rest
