"""The bundled sample: the ICT-FaceKit face region and a real AnimFace take."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FileFormatError, InputError
from ..structures import Mesh
from ..typing import FloatArray, IntArray

__all__ = ["IctSample", "bundled_path", "load_ict_sample"]

BUNDLED_FILES = (
    "ict_face_sample.npz",
    "eyebrows.c3d",
    "ict_generic_map.json",
    "README.md",
    "LICENSE-ICT-FaceKit.txt",
)
"""The files shipped in ``facecap/data``."""


@dataclass(frozen=True, eq=False)
class IctSample:
    """The ICT-FaceKit face region in millimetres (MIT licence; see ``facecap/data/README.md``).

    All arrays are read-only: the sample is loaded once and shared.

    Attributes
    ----------
    mesh : Mesh
        Neutral generic face: 9,409 vertices, 9,230 quads (kept for export),
        18,460 fan triangles, UVs; ``source_unit`` 'mm'.
    expression_deltas : (53, n, 3) float64 array, mm
        ARKit-style expression blendshapes as offsets from the neutral
        (stored as float32; the storage error is below 2e-6 mm).
    expression_names : tuple of str, length 53
        ``browDown_L`` ... ``noseSneer_R``; ``_L`` is the subject's left (+x).
    identity_deltas : (8, n, 3) float64 array, mm
        The first 8 ICT identity shapes as offsets from the neutral.
    identity_names : tuple of str, length 8
    landmarks : (68,) int64 array
        The ICT model's 68 facial landmark vertices (dlib-68 order).
    region_labels : (n,) int64 array
        Face region of each vertex, an index into ``region_names``.
    region_names : tuple of str
        ``('forehead', 'brows', 'eyes', 'nose', 'cheeks', 'mouth', 'chin_jaw',
        'other')``; 'other' is everything outside the ICT narrow face area
        (ears, scalp, sides of the head, neck). See ``docs/synthetic_data.md``.

    Notes
    -----
    Frame: x to the subject's left, y up, z out of the face; the nose tip is
    near (0, 4, 131) mm.
    """

    mesh: Mesh
    expression_deltas: FloatArray
    expression_names: tuple[str, ...]
    identity_deltas: FloatArray
    identity_names: tuple[str, ...]
    landmarks: IntArray
    region_labels: IntArray
    region_names: tuple[str, ...]

    @property
    def n_vertices(self) -> int:
        """Number of vertices n (9,409)."""
        return self.mesh.n_vertices

    def face(self, identity: Any = None) -> Mesh:
        """The neutral face of a person: ``neutral + sum_i a_i identity_deltas[i]``.

        Parameters
        ----------
        identity : (k,) float array, k <= 8, optional
            Identity coefficients (the first k identity shapes); None gives
            the generic face (this sample's own ``mesh``).

        Returns
        -------
        Mesh
            Same topology and UVs, new vertex positions (mm).

        Raises
        ------
        InputError
            If ``identity`` is not a finite 1-D array of at most 8 numbers.
        """
        if identity is None:
            return self.mesh
        try:
            a = np.asarray(identity, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"identity: expected a 1-D array of numbers, got {identity!r}") from None
        k = self.identity_deltas.shape[0]
        if a.ndim != 1 or a.size > k or not np.all(np.isfinite(a)):
            raise InputError(f"identity: expected at most {k} finite coefficients, got shape {a.shape}")
        V = self.mesh.vertices + np.tensordot(a, self.identity_deltas[: a.size], axes=1)
        return self.mesh.with_vertices(V)


def bundled_path(name: str) -> Path:
    """Path of a file bundled in ``facecap/data``.

    Parameters
    ----------
    name : {'ict_face_sample.npz', 'eyebrows.c3d', 'ict_generic_map.json', 'README.md', 'LICENSE-ICT-FaceKit.txt'}

    Returns
    -------
    Path

    Raises
    ------
    InputError
        If ``name`` is not a bundled file.
    FileFormatError
        If the file is missing from the installation.

    Examples
    --------
    >>> bundled_path("eyebrows.c3d").name
    'eyebrows.c3d'
    """
    if name not in BUNDLED_FILES:
        raise InputError(f"name: no bundled file {name!r}; expected one of {list(BUNDLED_FILES)}")
    path = Path(str(resources.files("facecap") / "data" / name))
    if not path.is_file():
        raise FileFormatError("bundled data file missing from the installation", path=str(path))
    return path


def _read_only(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@lru_cache(maxsize=1)
def load_ict_sample() -> IctSample:
    """Load the bundled ICT face sample (cached: the same read-only object every call).

    Returns
    -------
    IctSample

    Raises
    ------
    FileFormatError
        If the bundled ``ict_face_sample.npz`` is missing or incomplete.

    Examples
    --------
    >>> sample = load_ict_sample()
    >>> sample.mesh.n_vertices, sample.expression_deltas.shape
    (9409, (53, 9409, 3))
    """
    path = bundled_path("ict_face_sample.npz")
    try:
        with np.load(path) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError) as exc:
        raise FileFormatError(f"cannot read the bundled sample ({exc})", path=str(path)) from None
    needed = ("neutral", "triangles", "polygon_sizes", "polygon_indices", "uvs", "uv_indices",
              "expression_deltas", "expression_names", "identity_deltas", "identity_names",
              "landmarks", "region_labels", "region_names")
    missing = [k for k in needed if k not in arrays]
    if missing:
        raise FileFormatError(f"bundled sample lacks {missing}; rebuild it with tools/build_sample.py", path=str(path))
    mesh = Mesh(
        vertices=arrays["neutral"].astype(np.float64),
        faces=arrays["triangles"].astype(np.int64),
        polygon_sizes=arrays["polygon_sizes"].astype(np.int64),
        polygon_indices=arrays["polygon_indices"].astype(np.int64),
        uvs=arrays["uvs"].astype(np.float64),
        uv_indices=arrays["uv_indices"].astype(np.int64),
        source_unit="mm",
        source_path=str(path),
    )
    for a in (mesh.vertices, mesh.faces, mesh.polygon_sizes, mesh.polygon_indices, mesh.uvs, mesh.uv_indices):
        if a is not None:
            _read_only(a)
    return IctSample(
        mesh=mesh,
        expression_deltas=_read_only(arrays["expression_deltas"].astype(np.float64)),
        expression_names=tuple(str(s) for s in arrays["expression_names"]),
        identity_deltas=_read_only(arrays["identity_deltas"].astype(np.float64)),
        identity_names=tuple(str(s) for s in arrays["identity_names"]),
        landmarks=_read_only(arrays["landmarks"].astype(np.int64)),
        region_labels=_read_only(arrays["region_labels"].astype(np.int64)),
        region_names=tuple(str(s) for s in arrays["region_names"]),
    )
