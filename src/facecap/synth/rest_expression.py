"""A resting expression that is not the scan's: the face a take starts from when the actor is not quite neutral."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..errors import InputError
from ..typing import FloatArray
from ..validate import as_positive
from ..io.ict_sample import IctSample, load_ict_sample

__all__ = ["RESTING_SHAPES", "as_rest_weights", "random_rest_expression"]

RESTING_SHAPES: tuple[tuple[str, ...], ...] = (
    ("mouthSmile_L", "mouthSmile_R"),
    ("browDown_L", "browDown_R"),
    ("browInnerUp_L", "browInnerUp_R"),
    ("mouthPress_L", "mouthPress_R"),
    ("mouthFrown_L", "mouthFrown_R"),
    ("eyeSquint_L", "eyeSquint_R"),
    ("cheekSquint_L", "cheekSquint_R"),
    ("eyeBlink_L", "eyeBlink_R"),
    ("jawOpen",),
    ("mouthRollLower",),
    ("mouthShrugUpper",),
    ("noseSneer_L", "noseSneer_R"),
)
"""Groups of ICT expressions an actor may hold at rest: a slight smile, lowered or knitted brows, pressed or
parted lips, narrowed eyes. A pair is one group: both sides held, within 30 % of each other."""

MAX_REST_WEIGHT = 0.35
"""Largest weight :func:`random_rest_expression` gives one expression: a resting face, not a performance."""


def as_rest_weights(rest_expression: Any, names: Sequence[str]) -> FloatArray:
    """The resting expression as one weight per expression name, (k,) float64 in [0, 1].

    ``rest_expression`` is None (neutral: zeros), a ``{name: weight}`` mapping or a (k,) array in the
    order of ``names``. Raises InputError naming the problem.
    """
    k = len(names)
    if rest_expression is None:
        return np.zeros(k)
    if isinstance(rest_expression, Mapping):
        weights = np.zeros(k)
        index = {name: i for i, name in enumerate(names)}
        for name, value in rest_expression.items():
            if name not in index:
                raise InputError(f"rest_expression: unknown expression {name!r}; expected one of the sample's names")
            weights[index[name]] = float(value)
    else:
        try:
            weights = np.array(rest_expression, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"rest_expression: expected None, a name -> weight mapping or ({k},) weights") from None
        if weights.shape != (k,):
            raise InputError(f"rest_expression: expected ({k},) weights, got shape {weights.shape}")
    if not np.all(np.isfinite(weights)) or weights.min() < 0 or weights.max() > 1:
        raise InputError("rest_expression: weights must be finite and within [0, 1]")
    return weights


def random_rest_expression(seed: int, *, mean_mm: float = 0.42, n_groups: tuple[int, int] = (2, 4),
                           sample: IctSample | None = None) -> dict[str, float]:
    """A random resting expression whose mean displacement over the face is ``mean_mm``.

    ``n_groups`` (inclusive range) of the :data:`RESTING_SHAPES` groups are drawn, each with a random
    strength (the sides of a pair within 30 % of each other), and all weights are scaled together so that
    the expression moves the face's vertices (every region but 'other': ears, scalp, neck) by ``mean_mm``
    on average, no weight above :data:`MAX_REST_WEIGHT` (the mean then falls short of ``mean_mm``).

    Parameters
    ----------
    seed : int
        The draw.
    mean_mm : float, default 0.42
        Mean displacement over the face, mm. The default is that of a measured real case: a slight smile
        and lowered brows, 0.42 mm over the face and about 1 mm at the mouth.
    n_groups : (int, int), default (2, 4)
        Fewest and most groups held.
    sample : IctSample, optional
        Default :func:`load_ict_sample`.

    Returns
    -------
    dict of str to float
        Expression name -> weight, for ``generate_performance(rest_expression=...)``.

    Examples
    --------
    >>> rest = random_rest_expression(3, mean_mm=0.4)
    >>> 2 <= len({name.rstrip("_LR") for name in rest}) <= 4, max(rest.values()) <= MAX_REST_WEIGHT
    (True, True)
    """
    sample = load_ict_sample() if sample is None else sample
    mean_mm = as_positive(mean_mm, name="mean_mm")
    lo, hi = int(n_groups[0]), int(n_groups[1])
    if not 1 <= lo <= hi <= len(RESTING_SHAPES):
        raise InputError(f"n_groups: expected 1 <= fewest <= most <= {len(RESTING_SHAPES)}, got {n_groups}")
    rng = np.random.default_rng([int(seed), 0x2E57])
    groups = rng.choice(len(RESTING_SHAPES), size=int(rng.integers(lo, hi + 1)), replace=False)
    raw: dict[str, float] = {}
    for g in groups:
        strength = rng.uniform(0.3, 1.0)
        for name in RESTING_SHAPES[g]:
            raw[name] = strength * (rng.uniform(0.7, 1.0) if len(RESTING_SHAPES[g]) > 1 else 1.0)
    names = list(sample.expression_names)
    rows = [names.index(name) for name in raw]
    w = np.array(list(raw.values()))
    face = sample.region_labels != sample.region_names.index("other")
    deltas = sample.expression_deltas[rows][:, face]  # (g, n_face, 3)
    mean_at_unit = float(np.linalg.norm(np.tensordot(w, deltas, axes=1), axis=1).mean())
    scale = min(mean_mm / mean_at_unit, MAX_REST_WEIGHT / float(w.max()))  # the mean is linear in the scale
    return {name: float(weight * scale) for name, weight in zip(raw, w)}
