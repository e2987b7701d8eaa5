"""facecap: facial performance capture, from a face scan and a mocap take to an animated scan."""

from __future__ import annotations

from .errors import (
    CorrespondenceError,
    FacecapError,
    FacecapWarning,
    FileFormatError,
    InputError,
    MarkerError,
    MeshError,
    SolverError,
)
from .structures import MarkerSequence, Mesh

__version__ = "0.1.0"

__all__ = [
    "CorrespondenceError",
    "FacecapError",
    "FacecapWarning",
    "FileFormatError",
    "InputError",
    "MarkerError",
    "MarkerSequence",
    "Mesh",
    "MeshError",
    "SolverError",
    "__version__",
]
