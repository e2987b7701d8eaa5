"""Mesh operators: hygiene checks, connected pieces, welding of duplicate vertices."""

from .check_mesh import MeshCheck, check_mesh
from .connected_pieces import connected_pieces
from .weld_duplicate_vertices import WeldedMesh, weld_duplicate_vertices

__all__ = ["check_mesh", "MeshCheck", "connected_pieces", "weld_duplicate_vertices", "WeldedMesh"]
