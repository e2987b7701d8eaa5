"""Mesh operators: hygiene checks, connected pieces, welding, Laplacian, curvature."""

from .check_mesh import MeshCheck, check_mesh
from .connected_pieces import connected_pieces
from .laplacian import LaplaceOperators, laplace_operators
from .mean_curvature import mean_curvature
from .weld_duplicate_vertices import WeldedMesh, weld_duplicate_vertices

__all__ = [
    "LaplaceOperators",
    "MeshCheck",
    "WeldedMesh",
    "check_mesh",
    "connected_pieces",
    "laplace_operators",
    "mean_curvature",
    "weld_duplicate_vertices",
]
