"""Reading and writing: meshes, marker takes, correspondence maps, animated results.

In the order a user meets them:

- :func:`read_mesh` (``read_mesh.py``): OBJ, PLY or glTF to a :class:`~facecap.Mesh`
  in mm, vertex order and count kept; :func:`write_mesh` (``write_mesh.py``) writes one back.
- :func:`read_markers` (``read_markers.py``): a C3D, TRC or CSV take to a
  :class:`~facecap.MarkerSequence` in mm, NaN in gaps; :func:`write_markers`
  (``write_markers.py``) writes one.
- :func:`read_correspondence` (``read_correspondence.py``): the marker -> scan
  map, and :func:`match_correspondence` to line it up with a take's labels.
- :class:`PerformanceWriter` (``write_performance.py``): the streamed output
  folder every command writes; :func:`read_performance_info` reads its
  metadata back. :class:`UsdPerformanceWriter` (``write_usd.py``) is its USD
  export (usd-core is imported only when a USD file is written).
- :func:`write_scan_plan` / :func:`read_scan_plan` (``scan_plan.py``) and
  :func:`write_registered_scans` / :func:`read_registered_scans`
  (``registered_scans.py``): the files of the scan workflow (``plan.json``, the
  bases folder); :func:`write_conditioned_take` / :func:`read_conditioned_take`
  (``conditioned_take.py``): the take conditioned once by ``plan-scans`` and read
  by the later steps, with :func:`file_sha256` to tell it is the same take.

The functions share their modules' names, so ``facecap.io.read_mesh`` is the
function; reach a module itself with ``importlib.import_module``.
"""

from __future__ import annotations

from .read_correspondence import Correspondence, CorrespondenceMatch, match_correspondence, read_correspondence
from .read_markers import MARKER_SUFFIXES, read_markers
from .read_mesh import read_mesh
from .conditioned_take import CONDITIONED_TAKE_FORMAT, file_sha256, read_conditioned_take, write_conditioned_take
from .registered_scans import BASES_MARKER_FILE, CONDITIONED_TAKE_FILE, read_registered_scans, write_registered_scans
from .scan_plan import PLAN_FORMAT, read_scan_plan, write_scan_plan
from .write_markers import write_markers
from .write_mesh import write_mesh
from .write_performance import EXPORT_FORMATS, PerformanceWriter, read_performance_info
from .write_usd import UsdPerformanceWriter

__all__ = [
    "read_mesh",
    "write_mesh",
    "read_markers",
    "MARKER_SUFFIXES",
    "write_markers",
    "read_correspondence",
    "match_correspondence",
    "Correspondence",
    "CorrespondenceMatch",
    "PerformanceWriter",
    "EXPORT_FORMATS",
    "read_performance_info",
    "UsdPerformanceWriter",
    "write_scan_plan",
    "read_scan_plan",
    "PLAN_FORMAT",
    "write_registered_scans",
    "read_registered_scans",
    "BASES_MARKER_FILE",
    "CONDITIONED_TAKE_FILE",
    "write_conditioned_take",
    "read_conditioned_take",
    "CONDITIONED_TAKE_FORMAT",
    "file_sha256",
]
