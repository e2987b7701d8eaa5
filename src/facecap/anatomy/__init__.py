"""Anatomy from the scan: bone, one tetrahedral soft-tissue mesh, muscles and skin (Sifakis et al. 2005, sec. 3).

In the order :func:`build_anatomy` uses them:

- :func:`anatomy_landmarks` (``anatomy_landmarks.py``): named skin landmarks
  from a JSON file, the 68 iBUG points or the ICT topology, and the face frame.
- :func:`tissue_thickness` (``tissue_thickness.py``): forensic soft-tissue
  depths at the landmarks, harmonically interpolated over the skin.
- :func:`soft_tissue_shell` (``soft_tissue_shell.py``): the bone surface
  inside the skin and the closed skin-bone-wall surface of the soft tissue.
- :func:`tetrahedralize_shell` (``tetrahedralize_shell.py``): one fTetWild
  tetrahedral mesh, positively oriented, and :func:`tet_quality`.
- :func:`jaw_joint` (``jaw_joint.py``): the condyles, the cranium-mandible cut and
  the band along it that holds to neither bone (:func:`in_jaw_gap`).
- :func:`embed_points` (``skin_embedding.py``): each scan vertex as a
  tetrahedron and four barycentric weights.
- :func:`facial_muscles` (``facial_muscles.py``): 36 muscles as
  per-tetrahedron volume fractions and fibre directions.
- :func:`build_anatomy` (``build_anatomy.py``): all of the above, as a
  :class:`FaceAnatomy` (``face_anatomy.py``), saved and read back by
  :meth:`FaceAnatomy.save` and :func:`load_anatomy`.
- :func:`render_anatomy_layout` (``render_anatomy_layout.py``): a PNG of the
  muscles over the skin, front and side.
"""

from __future__ import annotations

from .anatomy_landmarks import (
    ANATOMY_LANDMARK_NAMES,
    AnatomyLandmarks,
    anatomy_landmarks,
    face_frame,
    landmarks_from_ibug68,
    read_landmarks,
)
from .build_anatomy import build_anatomy
from .face_anatomy import ANATOMY_FORMAT, FaceAnatomy, load_anatomy
from .facial_muscles import MUSCLE_NAMES, MuscleFields, MuscleSpec, facial_muscles, muscle_specs
from .jaw_joint import JAW_GAP_MM, JawJoint, in_jaw_gap, is_mandible, jaw_joint
from .render_anatomy_layout import render_anatomy_layout
from .skin_embedding import SkinEmbedding, embed_points, embedding_matrix
from .soft_tissue_shell import PART_BONE, PART_RIM, PART_SKIN, PART_WALL, SoftTissueShell, soft_tissue_shell
from .tetrahedralize_shell import TetMesh, TetQuality, tet_quality, tet_volumes, tetrahedralize_shell
from .tissue_thickness import MIN_TISSUE_MM, TISSUE_DEPTH_MM, tissue_thickness

__all__ = [
    "ANATOMY_FORMAT",
    "ANATOMY_LANDMARK_NAMES",
    "AnatomyLandmarks",
    "FaceAnatomy",
    "JAW_GAP_MM",
    "JawJoint",
    "MIN_TISSUE_MM",
    "MUSCLE_NAMES",
    "MuscleFields",
    "MuscleSpec",
    "PART_BONE",
    "PART_RIM",
    "PART_SKIN",
    "PART_WALL",
    "SkinEmbedding",
    "SoftTissueShell",
    "TISSUE_DEPTH_MM",
    "TetMesh",
    "TetQuality",
    "anatomy_landmarks",
    "build_anatomy",
    "embed_points",
    "embedding_matrix",
    "face_frame",
    "facial_muscles",
    "in_jaw_gap",
    "is_mandible",
    "jaw_joint",
    "landmarks_from_ibug68",
    "load_anatomy",
    "muscle_specs",
    "read_landmarks",
    "render_anatomy_layout",
    "soft_tissue_shell",
    "tet_quality",
    "tet_volumes",
    "tetrahedralize_shell",
    "tissue_thickness",
]
