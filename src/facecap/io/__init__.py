"""Reading and writing: meshes, marker takes, correspondence maps, animated results."""

from __future__ import annotations

from .read_correspondence import Correspondence, CorrespondenceMatch, match_correspondence, read_correspondence
from .read_markers import read_markers
from .read_mesh import read_mesh
from .write_markers import write_markers
from .write_mesh import write_mesh
from .write_performance import EXPORT_FORMATS, PerformanceWriter, read_performance_info

__all__ = [
    "Correspondence",
    "CorrespondenceMatch",
    "EXPORT_FORMATS",
    "match_correspondence",
    "read_correspondence",
    "read_markers",
    "write_markers",
    "PerformanceWriter",
    "read_mesh",
    "read_performance_info",
    "write_mesh",
]
