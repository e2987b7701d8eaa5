"""Mesh operators: hygiene checks, connected pieces, welding, Laplacian, curvature.

In the order a user meets them:

- :func:`check_mesh` (``check_mesh.py``): the defects that make solvers fail
  on real scans, as a :class:`MeshCheck`.
- :func:`connected_pieces` (``connected_pieces.py``): which vertices belong together.
- :func:`facing_outward` (``facing_outward.py``): whether a surface's triangles
  face away from it (outward winding) or into it, from its geometry alone.
- :func:`resample_polyline` (``resample_polyline.py``): points evenly spaced along
  a curve (a muscle's centre line, a wrinkle), as a :class:`ResampledPolyline`.
- :func:`nearest_on_polyline` (``nearest_on_polyline.py``): each point's distance to a
  polyline and where along it its nearest point lies (a wrinkle's valley line).
- :class:`UVRaster` (``uv_raster.py``): which UV triangle and barycentric weights each texel of a
  square map takes, with edge padding (the detail's maps).
- :func:`face_normals`, :func:`vertex_normals` (``vertex_normals.py``): normals
  of one frame or a stack, everywhere or at a few vertices (area-weighted).
- :func:`duplicate_representatives` (``duplicate_representatives.py``): which vertices sit at
  the same position, as each one's lowest-numbered duplicate.
- :func:`weld_duplicate_vertices` (``weld_duplicate_vertices.py``): one vertex
  per position across UV seams, as a :class:`WeldedMesh`.
- :func:`laplace_operators` (``laplacian.py``): cotangent Laplacian and mixed
  Voronoi mass (Meyer et al. 2003), as :class:`LaplaceOperators`.
- :func:`surface_colors`, :func:`texel_size_mm`, :func:`has_colors`, :func:`sample_image`
  (``surface_colors.py``): a mesh's colour at points on it, from its texture or its vertex colours,
  how fine a texture is, and the bilinear lookup of an image at UVs.
- :func:`median_edge_length` (``median_edge_length.py``): the median length of the
  triangles' sides, the scale a mesh is sampled at.
- :func:`mean_curvature` (``mean_curvature.py``): per-vertex mean curvature
  from local quadric fits.
- :class:`LocalFrameDetails`, :func:`local_frames` (``local_frame_details.py``):
  detail displacements stored in a base surface's local frames and added back
  on a changed base (Kobbelt et al. 1999).
- :func:`review_mesh` (``review_mesh.py``): a decimated mesh made of a subset of
  the scan's own vertices, for review files, as a :class:`ReviewMesh`.
- :class:`SpdFactor` (``factor_spd.py``): the sparse SPD factorisation every
  solver of a mesh's operators shares (PARDISO, or SciPy's SuperLU where MKL is
  missing); :func:`available_backends` those that load here, :func:`load_backend` loads one's
  libraries now (before other threads start).
"""

from __future__ import annotations

from .check_mesh import MeshCheck, check_mesh
from .connected_pieces import connected_pieces
from .facing_outward import facing_outward
from .factor_spd import SpdFactor, available_backends, load_backend
from .laplacian import LaplaceOperators, laplace_operators
from .local_frame_details import LocalFrameDetails, local_frames
from .mean_curvature import DEFAULT_FEATURE_THRESHOLD, mean_curvature
from .median_edge_length import median_edge_length
from .nearest_on_polyline import nearest_on_polyline
from .resample_polyline import ResampledPolyline, resample_polyline
from .review_mesh import ReviewMesh, review_mesh
from .surface_colors import has_colors, sample_image, surface_colors, texel_size_mm
from .uv_raster import UVRaster
from .vertex_normals import face_normals, vertex_normals
from .weld_duplicate_vertices import WeldedMesh, weld_duplicate_vertices
from .duplicate_representatives import duplicate_representatives

__all__ = [
    "UVRaster",
    "surface_colors",
    "texel_size_mm",
    "has_colors",
    "sample_image",
    "check_mesh",
    "SpdFactor",
    "available_backends",
    "load_backend",
    "MeshCheck",
    "connected_pieces",
    "facing_outward",
    "weld_duplicate_vertices",
    "duplicate_representatives",
    "WeldedMesh",
    "laplace_operators",
    "LaplaceOperators",
    "LocalFrameDetails",
    "local_frames",
    "mean_curvature",
    "DEFAULT_FEATURE_THRESHOLD",
    "median_edge_length",
    "review_mesh",
    "ReviewMesh",
    "resample_polyline",
    "nearest_on_polyline",
    "ResampledPolyline",
    "face_normals",
    "vertex_normals",
]
