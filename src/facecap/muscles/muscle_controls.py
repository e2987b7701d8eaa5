"""The controls of the muscle-driven face: activations, cranium and mandible frames (Sifakis et al. 2005, sec. 5, 8)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError
from ..typing import FloatArray

__all__ = ["MuscleControls"]

_IDENTITY_34 = np.hstack([np.eye(3), np.zeros((3, 1))])


def _affine(value: Any, name: str) -> FloatArray:
    try:
        A = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name}: expected a (3, 4) affine transform [M | t] ({exc})") from None
    if A.shape != (3, 4) or not np.all(np.isfinite(A)):
        raise InputError(f"{name}: expected a finite (3, 4) affine transform [M | t], got shape {A.shape}")
    return A


@dataclass(frozen=True, eq=False)
class MuscleControls:
    """One set of controls ``c = (a, b)``: muscle activations and the two bone frames.

    Attributes
    ----------
    activations : (k,) float64 array
        Muscle activations, physically in [0, 1].
    cranium : (3, 4) float64 array, mm
        ``[M_c | t_c]``: the head's frame, rest (scan) coordinates to world, ``x -> M_c x + t_c``.
    mandible : (3, 4) float64 array, mm
        ``[M_m | t_m]``: the jaw's frame relative to the cranium, in the cranium's (rest)
        coordinates: a mandible node at rest ``X`` sits at ``M_c (M_m X + t_m) + t_c``.

    Notes
    -----
    Both frames are general affine maps, as in the paper's section 8: the marker
    positions are then linear in the cranium's 12 coefficients, so a Gauss-Newton step
    captures any rigid head motion exactly; rigidity (``M^T M = I``) is a penalty of the
    solver (:func:`~facecap.muscles.control_penalty`). :meth:`as_vector` packs the
    controls as ``[a, vec(M_c), t_c, vec(M_m), t_m]`` (``vec`` row-major), length ``k + 24``.

    Examples
    --------
    >>> c = MuscleControls.rest(3)
    >>> c.as_vector().shape, bool(np.all(MuscleControls.from_vector(c.as_vector(), 3).cranium == c.cranium))
    ((27,), True)
    """

    activations: FloatArray
    cranium: FloatArray
    mandible: FloatArray

    def __post_init__(self) -> None:
        a = np.array(self.activations, dtype=np.float64).reshape(-1)
        if not np.all(np.isfinite(a)):
            raise InputError("activations: expected finite values")
        object.__setattr__(self, "activations", a)
        object.__setattr__(self, "cranium", _affine(self.cranium, "cranium"))
        object.__setattr__(self, "mandible", _affine(self.mandible, "mandible"))

    @property
    def n_muscles(self) -> int:
        """Number of activations k."""
        return int(self.activations.size)

    @classmethod
    def rest(cls, n_muscles: int) -> MuscleControls:
        """No activation, both frames the identity (the scan's pose)."""
        return cls(np.zeros(int(n_muscles)), _IDENTITY_34.copy(), _IDENTITY_34.copy())

    def as_vector(self) -> FloatArray:
        """``[a, vec(M_c), t_c, vec(M_m), t_m]``, (k + 24,) float64."""
        c, m = self.cranium, self.mandible
        return np.concatenate([self.activations, c[:, :3].ravel(), c[:, 3], m[:, :3].ravel(), m[:, 3]])

    @classmethod
    def from_vector(cls, vector: Any, n_muscles: int) -> MuscleControls:
        """The inverse of :meth:`as_vector`."""
        v = np.asarray(vector, dtype=np.float64).reshape(-1)
        k = int(n_muscles)
        if v.size != k + 24:
            raise InputError(f"vector: expected {k + 24} values for {k} muscles, got {v.size}")
        cranium = np.hstack([v[k:k + 9].reshape(3, 3), v[k + 9:k + 12, None]])
        mandible = np.hstack([v[k + 12:k + 21].reshape(3, 3), v[k + 21:k + 24, None]])
        return cls(v[:k].copy(), cranium, mandible)
