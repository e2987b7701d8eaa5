"""Which pixels wear which paint: the per-colour SVM of Bickel et al. (2007), section 5.1, and its clean-up.

The classifier is trained once, from the first frame and the mask a user paints on it, and then
applied to every frame. An RBF support vector machine per paint colour costs a kernel sum over its
support vectors for every pixel (about 1.4M a frame at 1384x1038); since its decision depends on
nothing but the pixel's colour, it is tabulated once over a quantised RGB cube and every frame is
classified by a table look-up.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..errors import InputError
from ..typing import FloatArray, IntArray

__all__ = [
    "PaintClassifier",
    "train_paint_classifier",
    "classify_paint",
    "clean_paint_labels",
    "separate_paint_colors",
    "paint_features",
    "mask_from_color_picks",
]

LUT_BINS = 64
"""Bins per RGB channel of the tabulated decision (64^3 = 262,144 colours; an 8-bit code's bin holds 4 codes)."""


def paint_features(rgb: Any) -> FloatArray:
    """The colour features the SVM sees: RGB and the chromaticity ``(r, g) / (r + g + b)``.

    Parameters
    ----------
    rgb : (..., 3) float array
        Colours in [0, 1] (the image's own encoding).

    Returns
    -------
    (..., 5) float64 array
        RGB, then the two chromaticities (which shading scales out: a shadowed paint keeps them).
    """
    C = np.asarray(rgb, dtype=np.float64)
    total = C.sum(axis=-1, keepdims=True) + 1e-3
    return np.concatenate([C, C[..., :2] / total], axis=-1)


def _as_rgb(image: Any, name: str = "image") -> FloatArray:
    from ..cameras.image_to_float import image_to_float

    A = image_to_float(image)
    if A.ndim != 3 or A.shape[2] not in (3, 4):
        raise InputError(f"{name}: expected an (H, W, 3) RGB image, got shape {A.shape}")
    return np.clip(A[..., :3], 0.0, 1.0)


def _erode(binary: np.ndarray, radius: int) -> np.ndarray:
    import cv2

    if radius <= 0:
        return binary
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    return cv2.erode(binary.astype(np.uint8), kernel).astype(bool)


def separate_paint_colors(image: Any, mask: Any, *, n_colors: int | None = None, max_colors: int = 6,
                          seed: int = 0) -> IntArray:
    """Split a binary mask covering every paint into one label per paint colour (k-means on chromaticity).

    Parameters
    ----------
    image : (H, W, 3) array
        The frame the mask was painted on (RGB).
    mask : (H, W) bool array
        Every painted pixel, whatever its colour.
    n_colors : int, optional
        How many paints; chosen by the silhouette score over 2..``max_colors`` if not given
        (one colour when no split scores above 0.5).
    max_colors : int, default 6
    seed : int, default 0
        Seeds k-means and the subsample.

    Returns
    -------
    (H, W) int64 array
        0 off the mask, ``1 + i`` on paint ``i``; paints ordered by decreasing pixel count.

    Raises
    ------
    InputError
        If the mask is empty or has fewer pixels than colours.
    """
    from sklearn.cluster import KMeans
    from sklearn.metrics import silhouette_score

    rgb = _as_rgb(image)
    M = np.asarray(mask, dtype=bool)
    if M.shape != rgb.shape[:2]:
        raise InputError(f"mask: shape {M.shape} does not match the image's {rgb.shape[:2]}")
    # cluster the mask's interior: stripe edges blend paint with skin
    inner = _erode(M, 1)
    if inner.sum() < 50:
        inner = M
    chroma = paint_features(rgb[inner])[:, 3:]
    if chroma.shape[0] == 0:
        raise InputError("mask: no painted pixel")
    rng = np.random.default_rng(seed)
    sample = chroma[rng.choice(chroma.shape[0], size=min(4000, chroma.shape[0]), replace=False)]
    if n_colors is None:
        best_k, best_score = 1, 0.5
        for k in range(2, max_colors + 1):
            if sample.shape[0] <= k:
                break
            labels = KMeans(k, n_init=4, random_state=seed).fit_predict(sample)
            score = silhouette_score(sample, labels, sample_size=min(2000, sample.shape[0]), random_state=seed)
            if score > best_score:
                best_k, best_score = k, score
        n_colors = best_k
    if n_colors < 1 or sample.shape[0] < n_colors:
        raise InputError(f"n_colors: {n_colors} colours from {sample.shape[0]} painted pixels")
    model = KMeans(n_colors, n_init=4, random_state=seed).fit(sample)
    assigned = model.predict(paint_features(rgb[M])[:, 3:])
    order = np.argsort(-np.bincount(assigned, minlength=n_colors), kind="stable")
    rank = np.empty(n_colors, dtype=np.int64)
    rank[order] = np.arange(n_colors)
    labels = np.zeros(M.shape, dtype=np.int64)
    labels[M] = 1 + rank[assigned]
    return labels


def mask_from_color_picks(image: Any, picks: Any, *, tolerance: float = 0.04, radius_px: int = 2) -> IntArray:
    """A paint mask made from colour picks: one picked pixel per paint instead of a painted mask.

    Parameters
    ----------
    image : (H, W, 3) array
        The first frame, RGB.
    picks : (k, 2) int array, px
        ``(u, v)`` (column, row) of one pixel on each paint, in paint order.
    tolerance : float, default 0.04
        Largest chromaticity distance (``(r, g) / (r + g + b)``, which shading scales out) from
        the picked colour; a pixel near two picks takes the nearer.
    radius_px : int, default 2
        The picked colour is the mean over this radius around each pick (noise).

    Returns
    -------
    (H, W) int64 array
        0 elsewhere, ``1 + i`` on paint ``i``: a mask for :func:`train_paint_classifier`.

    Raises
    ------
    InputError
        If a pick lies outside the image.
    """
    rgb = _as_rgb(image)
    H, W = rgb.shape[:2]
    P = np.asarray(picks)
    if P.ndim != 2 or P.shape[1] != 2 or P.shape[0] < 1:
        raise InputError(f"picks: expected (k, 2) pixel positions (u, v), got shape {P.shape}")
    chroma = paint_features(rgb)[..., 3:]
    picked = []
    for i, (u, v) in enumerate(np.round(P).astype(np.int64)):
        if not (0 <= u < W and 0 <= v < H):
            raise InputError(f"picks: pick {i} at (u, v) = ({u}, {v}) is outside the {W}x{H} image")
        window = chroma[max(v - radius_px, 0):v + radius_px + 1, max(u - radius_px, 0):u + radius_px + 1]
        picked.append(window.reshape(-1, 2).mean(axis=0))
    distance = np.linalg.norm(chroma[:, :, None, :] - np.asarray(picked)[None, None], axis=-1)
    nearest = distance.argmin(axis=-1)
    return np.where(distance.min(axis=-1) <= tolerance, nearest + 1, 0).astype(np.int64)


def _label_image(image: FloatArray, mask: Any, n_colors: int | None) -> IntArray:
    """Any of the accepted mask forms as one label image (0 bare, 1 + i paint i)."""
    H, W = image.shape[:2]
    if isinstance(mask, (list, tuple)) or (np.ndim(mask) == 3):
        masks = [np.asarray(m) for m in mask]
        labels = np.zeros((H, W), dtype=np.int64)
        for i, m in enumerate(masks):
            if m.shape != (H, W):
                raise InputError(f"mask {i}: shape {m.shape} does not match the image's {(H, W)}")
            if not np.any(m > 0):
                raise InputError(f"mask {i}: paint colour {i} has no pixel (the mask is empty)")
            labels[(m > 0) & (labels == 0)] = i + 1
        return labels
    M = np.asarray(mask)
    if M.ndim != 2 or M.shape != (H, W):
        raise InputError(f"mask: expected an (H, W) = {(H, W)} image, got shape {M.shape}")
    if M.dtype == bool or set(np.unique(M).tolist()) <= {0, 255}:
        return separate_paint_colors(image, M > 0, n_colors=n_colors)
    if not np.issubdtype(M.dtype, np.integer) or M.min() < 0:
        raise InputError(f"mask: expected 0 for bare skin and 1 + i for paint i (integers), got {M.dtype}")
    return M.astype(np.int64)


@dataclass(frozen=True)
class PaintClassifier:
    """One RBF soft-margin SVM per paint colour, each against everything else, tabulated over RGB.

    Attributes
    ----------
    machines : tuple of sklearn.svm.SVC
        Machine ``i`` separates paint ``i`` (positive) from skin and the other paints.
    table : (n_colors, LUT_BINS**3) float32 array
        Each machine's decision function at the centre of every bin of the RGB cube.
    mean_colors : (n_colors, 3) float64 array
        Mean RGB of each paint's training pixels.
    label_table : (LUT_BINS**3,) uint8 array
        The label :func:`classify_paint` gives each bin (0 skin, ``1 + i`` paint ``i``).
    mask_labels : (H, W) int64 array
        The training mask as labels (0 bare, ``1 + i`` paint ``i``): after separating the
        colours of a binary mask, the wrinkles the tracker follows start from it.
    """

    machines: tuple[Any, ...]
    table: FloatArray
    mean_colors: FloatArray
    label_table: np.ndarray
    mask_labels: IntArray

    @property
    def n_colors(self) -> int:
        return len(self.machines)

    def decision(self, rgb: Any) -> FloatArray:
        """The machines' own decision functions at colours ``rgb`` ((m, 3) in [0, 1]): ``(m, n_colors)``."""
        X = paint_features(np.asarray(rgb, dtype=np.float64).reshape(-1, 3))
        return np.stack([machine.decision_function(X) for machine in self.machines], axis=1)

    def table_decision(self, rgb: Any) -> FloatArray:
        """The tabulated decision functions at colours ``rgb`` ((m, 3) in [0, 1]): ``(m, n_colors)``."""
        return self.table[:, _bin_index(np.asarray(rgb, dtype=np.float32).reshape(-1, 3))].T

    def classify(self, image: Any) -> IntArray:
        """Paint label per pixel: 0 skin, ``1 + i`` paint ``i`` (see :func:`classify_paint`)."""
        return classify_paint(self, image)


def _bin_index(rgb: np.ndarray) -> np.ndarray:
    q = np.minimum((np.clip(rgb, 0.0, 1.0) * LUT_BINS).astype(np.int64), LUT_BINS - 1)
    return (q[..., 0] * LUT_BINS + q[..., 1]) * LUT_BINS + q[..., 2]


def train_paint_classifier(first_frame_image: Any, mask: Any, *, n_colors: int | None = None, C: float = 10.0,
                           gamma: float | str = "scale", samples_per_class: int = 1500, edge_px: int = 2,
                           seed: int = 0) -> PaintClassifier:
    """Train the per-colour SVMs from the first frame and the mask painted on it.

    Parameters
    ----------
    first_frame_image : (H, W, 3) uint8, uint16 or float array
        The frame the mask was painted on, RGB.
    mask : (H, W) array, or sequence of (H, W) arrays
        One of: a label image (0 bare skin, ``1 + i`` where paint ``i`` covers the pixel: the
        generator's ``mask_<cam>.png``, or :func:`mask_from_color_picks`'); a binary mask (bool,
        or 0 and 255) covering every paint,
        whose colours are then separated by :func:`separate_paint_colors`; or one binary mask
        per colour.
    n_colors : int, optional
        For a binary mask: how many paints (chosen automatically if not given).
    C : float, default 10.0
        Soft-margin penalty of the SVMs.
    gamma : float or 'scale', default 'scale'
        RBF kernel width (scikit-learn's: ``'scale'`` is ``1 / (n_features * X.var())``).
    samples_per_class : int, default 1500
        Training pixels drawn per paint, and twice as many from the rest (the machines'
        cost grows with their support vectors, not with the image).
    edge_px : int, default 2
        Pixels within this distance of a mask boundary are left out of training: there the
        image blends paint with skin and a painted mask is least sure.
    seed : int, default 0

    Returns
    -------
    PaintClassifier

    Raises
    ------
    InputError
        If the image is not RGB, the mask's shape differs from the image's, or a paint
        colour has no pixel in the mask (naming the colour).

    Notes
    -----
    The paper (section 5.1) trains a binary SVM with L2 soft margin and RBF kernel per marker
    colour from a mask of the first frame; here scikit-learn's ``SVC`` (libsvm, hinge soft
    margin) on RGB plus chromaticity (:func:`paint_features`). The decision of every machine is
    then evaluated once at the centres of a ``LUT_BINS^3`` RGB cube.

    References
    ----------
    Bickel, Botsch, Angst, Matusik, Otaduy, Pfister, Gross (2007). Multi-scale capture of facial
    geometry and motion. ACM TOG 26(3), section 5.1.
    """
    from sklearn.svm import SVC

    rgb = _as_rgb(first_frame_image, "first_frame_image")
    labels = _label_image(rgb, mask, n_colors)
    k = int(labels.max())
    if k < 1:
        raise InputError("mask: no painted pixel (every value is 0)")
    counts = np.bincount(labels.ravel(), minlength=k + 1)
    empty = [i for i in range(k) if counts[i + 1] == 0]
    if empty:
        raise InputError(f"mask: paint colour {empty[0]} (mask value {empty[0] + 1}) has no pixel; "
                         f"colours present: {[i for i in range(k) if counts[i + 1]]}")
    rng = np.random.default_rng(seed)
    features = paint_features(rgb)
    machines = []
    means = np.zeros((k, 3))
    for i in range(k):
        positive = _erode(labels == i + 1, edge_px)
        negative = _erode(labels != i + 1, edge_px)
        if positive.sum() < 10:
            positive = labels == i + 1
        pos = np.flatnonzero(positive.ravel())
        neg = np.flatnonzero(negative.ravel())
        pos = rng.choice(pos, size=min(samples_per_class, pos.size), replace=False)
        # half the negatives near the paint (the skin and paints it must be told from), half anywhere
        near = np.flatnonzero((negative & ~_erode(~(labels == i + 1), 25)).ravel())
        n_near = min(samples_per_class, near.size)
        neg = np.concatenate([rng.choice(near, size=n_near, replace=False) if n_near else near,
                              rng.choice(neg, size=min(2 * samples_per_class - n_near, neg.size), replace=False)])
        X = np.concatenate([features.reshape(-1, 5)[pos], features.reshape(-1, 5)[neg]])
        y = np.concatenate([np.ones(pos.size), np.zeros(neg.size)])
        machines.append(SVC(kernel="rbf", C=C, gamma=gamma).fit(X, y))
        means[i] = rgb.reshape(-1, 3)[pos].mean(axis=0)
    centres = (np.arange(LUT_BINS) + 0.5) / LUT_BINS
    cube = np.stack(np.meshgrid(centres, centres, centres, indexing="ij"), axis=-1).reshape(-1, 3)
    cube_features = paint_features(cube)
    table = np.stack([m.decision_function(cube_features) for m in machines]).astype(np.float32)
    label_table = np.where(table.max(axis=0) > 0, table.argmax(axis=0) + 1, 0).astype(np.uint8)
    return PaintClassifier(machines=tuple(machines), table=table, mean_colors=means, label_table=label_table,
                           mask_labels=labels)


def classify_paint(classifier: PaintClassifier, image: Any, *, use_table: bool = True) -> IntArray:
    """Label every pixel with the paint it wears: the most confident machine that says yes.

    Parameters
    ----------
    classifier : PaintClassifier
    image : (H, W, 3) array
        RGB, any of :func:`~facecap.cameras.image_to_float`'s types.
    use_table : bool, default True
        Look the decisions up in the tabulated cube (about 30 ms a 1384x1038 frame); False
        evaluates the SVMs themselves (seconds per frame; the reference).

    Returns
    -------
    (H, W) int64 array
        0 skin (every decision negative), ``1 + i`` paint ``i``.
    """
    A = np.asarray(image)
    if use_table and A.dtype == np.uint8 and A.ndim == 3 and A.shape[2] in (3, 4):
        # an 8-bit code's bin is code >> 2 (64 bins): no float image needed
        q = A[..., :3] >> 2
        index = (q[..., 0].astype(np.int32) << 12) | (q[..., 1].astype(np.int32) << 6) | q[..., 2]
        return classifier.label_table[index].astype(np.int64)
    rgb = _as_rgb(image)
    H, W = rgb.shape[:2]
    if use_table:
        return classifier.label_table[_bin_index(rgb)].astype(np.int64)
    scores = classifier.decision(rgb.reshape(-1, 3)).T
    best = scores.argmax(axis=0)
    labels = np.where(scores[best, np.arange(best.size)] > 0, best + 1, 0)
    return labels.reshape(H, W).astype(np.int64)


def clean_paint_labels(labels: Any, n_colors: int, *, opening_px: int = 1, closing_px: int = 2) -> IntArray:
    """Remove isolated misclassified pixels and fill pinholes: a morphological opening, then a closing, per colour.

    Parameters
    ----------
    labels : (H, W) int array
        0 skin, ``1 + i`` paint ``i`` (from :func:`classify_paint`).
    n_colors : int
    opening_px, closing_px : int, default 1 and 2
        Radii of the elliptic structuring elements (0 skips the step).

    Returns
    -------
    (H, W) int64 array
        The cleaned labels (where two colours' closings meet, the lower colour index wins).
    """
    import cv2

    L = np.asarray(labels)
    out = np.zeros(L.shape, dtype=np.int64)
    for i in range(n_colors):
        binary = (L == i + 1).astype(np.uint8)
        if opening_px > 0:
            kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * opening_px + 1,) * 2)
            binary = cv2.morphologyEx(binary, cv2.MORPH_OPEN, kernel)
        if closing_px > 0:
            kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * closing_px + 1,) * 2)
            binary = cv2.morphologyEx(binary, cv2.MORPH_CLOSE, kernel)
        out[(binary > 0) & (out == 0)] = i + 1
    return out
