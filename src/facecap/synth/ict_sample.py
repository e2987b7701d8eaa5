"""The bundled sample: the ICT-FaceKit face region and a real AnimFace take."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..structures import Mesh

__all__ = ["IctSample", "load_ict_sample", "bundled_path"]

_BUNDLED = ("ict_face_sample.npz", "eyebrows.c3d", "ict_generic_map.json", "README.md", "LICENSE-ICT-FaceKit.txt")


@dataclass(frozen=True, eq=False)
class IctSample:
    """The ICT-FaceKit face region in millimetres (MIT licence; see ``facecap/data/README.md``).

    Attributes
    ----------
    mesh : Mesh
        Neutral generic face: 9,409 vertices, 9,230 polygons (quads kept), UVs, mm.
    expression_deltas : (53, n, 3) float32 array, mm
        ARKit-style blendshapes as offsets from the neutral.
    expression_names : tuple of str
    identity_deltas : (8, n, 3) float32 array, mm
        The first 8 ICT identity shapes as offsets from the neutral.
    landmarks : (68,) int64 array
        dlib-68 landmark vertices.
    region_labels : (n,) int64 array
        Face region of each vertex, an index into ``region_names``.
    region_names : tuple of str
    """

    mesh: Mesh
    expression_deltas: np.ndarray
    expression_names: tuple[str, ...]
    identity_deltas: np.ndarray
    landmarks: np.ndarray
    region_labels: np.ndarray
    region_names: tuple[str, ...]

    def face(self, identity: np.ndarray | None = None) -> Mesh:
        """The neutral face of a person: ``neutral + sum_i a_i identity_deltas[i]``.

        Parameters
        ----------
        identity : (k,) float array, k <= 8, optional
            Identity coefficients; None gives the generic face.
        """
        if identity is None:
            return self.mesh
        a = np.asarray(identity, dtype=np.float64)
        if a.ndim != 1 or a.size > self.identity_deltas.shape[0]:
            raise InputError(f"identity: expected at most {self.identity_deltas.shape[0]} coefficients, got {a.shape}")
        V = self.mesh.vertices + np.tensordot(a, self.identity_deltas[: a.size].astype(np.float64), axes=1)
        return self.mesh.with_vertices(V)


def bundled_path(name: str) -> Path:
    """Path of a bundled data file (``'eyebrows.c3d'``, ``'ict_generic_map.json'``, ...)."""
    if name not in _BUNDLED:
        raise InputError(f"no bundled file {name!r}; have {list(_BUNDLED)}")
    return Path(str(resources.files("facecap") / "data" / name))


@lru_cache(maxsize=1)
def load_ict_sample() -> IctSample:
    """Load the bundled ICT face sample (cached; about 0.2 s the first time).

    Examples
    --------
    >>> sample = load_ict_sample()
    >>> sample.mesh.n_vertices, sample.expression_deltas.shape[0]
    (9409, 53)
    """
    with np.load(bundled_path("ict_face_sample.npz")) as data:
        sizes = data["polygon_sizes"].astype(np.int64)
        mesh = Mesh(
            vertices=data["neutral"].astype(np.float64),
            faces=data["triangles"].astype(np.int64),
            polygon_sizes=sizes,
            polygon_indices=data["polygon_indices"].astype(np.int64),
            uvs=data["uvs"].astype(np.float64),
            uv_indices=data["uv_indices"].astype(np.int64),
            source_unit="mm",
            source_path="facecap/data/ict_face_sample.npz",
        )
        deltas = data["expression_deltas"]
        deltas.setflags(write=False)
        return IctSample(
            mesh=mesh,
            expression_deltas=deltas,
            expression_names=tuple(str(s) for s in data["expression_names"]),
            identity_deltas=data["identity_deltas"],
            landmarks=data["landmarks"].astype(np.int64),
            region_labels=data["region_labels"].astype(np.int64),
            region_names=tuple(str(s) for s in data["region_names"]),
        )
