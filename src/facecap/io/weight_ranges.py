"""Blend-shape weights moved into [0, 1], the range every client plays without clamping.

Blender clamps a shape key's value to its slider range, [0, 1] unless widened,
and its glTF and USD importers do not widen it to the animation's values (its
glTF importer looks at the first keyframe only; its USD importer not at all).
The thin shell's weights are marker displacements in mm (tens of mm), and
principal-component weights are signed. So both writers store each target
``D_j`` with weights ``w_j(t)`` in ``[lo_j, hi_j]`` as

    ``(hi_j - lo_j) D_j`` with weights ``(w_j(t) - lo_j) / (hi_j - lo_j)`` in [0, 1],

and move ``sum_j lo_j D_j`` into the base mesh. Every frame is the same
(exact in real arithmetic; float32 storage adds about 1e-7 of the motion).
The base mesh is then the shape at all-zero weights, not the rest shape: the
rest shape is at the weights :func:`to_unit_range` returns as
``rest_weights`` (``-lo_j / (hi_j - lo_j)``), which the files record
(glTF ``asset.extras.facecap.rest_weights``, USD ``customData``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["to_unit_range", "UnitRangeWeights"]


class UnitRangeWeights(NamedTuple):
    """A blend-shape animation with its weights in [0, 1]."""

    base_offset: np.ndarray
    """(n, 3) float64: what to add to the rest shape to get the base mesh (all weights zero)."""
    targets: np.ndarray
    """(m, n, 3) float32: the rescaled targets."""
    weights: np.ndarray
    """(T, m) float32 in [0, 1]."""
    rest_weights: np.ndarray
    """(m,) float64: the weights that give the rest shape (in [0, 1] unless a target's weight never changes)."""


def to_unit_range(targets: np.ndarray, weights: np.ndarray, *, overwrite_targets: bool = False) -> UnitRangeWeights:
    """Rescale ``targets`` (m, n, 3) and ``weights`` (T, m) so every weight lies in [0, 1] (see the module docstring).

    Targets whose weights already lie in [0, 1] are kept as they are; a
    constant weight (``hi == lo``) moves wholly into the base. With
    ``overwrite_targets`` a writable float32 ``targets`` is rescaled in place
    and returned as ``.targets`` (as SciPy's ``overwrite_a``: for a caller
    that made the array and needs no copy of it; at 700k vertices and 48
    targets a fresh 0.4 GB copy took 1.2 s).
    """
    D = np.asarray(targets)
    W = np.asarray(weights, dtype=np.float64)
    m = D.shape[0]
    lo = W.min(axis=0) if W.shape[0] else np.zeros(m)
    hi = W.max(axis=0) if W.shape[0] else np.zeros(m)
    inside = (lo >= 0.0) & (hi <= 1.0)
    lo = np.where(inside, 0.0, lo)
    span = np.where(inside, 1.0, hi - lo)
    flat = span <= 0  # a weight that never changes: all of it goes into the base
    span = np.where(flat, 1.0, span)
    base_offset = np.zeros(D.shape[1:], np.float64)
    in_place = overwrite_targets and D.dtype == np.float32 and D.flags.writeable
    scaled = D if in_place else np.empty(D.shape, np.float32)
    for j in range(m):  # one target at a time: no float64 copy of all of them
        if lo[j] != 0.0:
            base_offset += lo[j] * D[j]
        np.multiply(D[j], np.float32(span[j]), out=scaled[j], casting="unsafe")
    new_weights = np.where(flat[None], 0.0, (W - lo[None]) / span[None])
    return UnitRangeWeights(
        base_offset=base_offset,
        targets=scaled,
        weights=np.clip(new_weights, 0.0, 1.0).astype(np.float32),
        rest_weights=-lo / span,
    )
