"""Reading and writing: meshes, marker takes, correspondence maps, animated results.

In the order a user meets them:

- :func:`read_mesh` (``read_mesh.py``): OBJ, PLY or glTF to a :class:`~facecap.Mesh`
  in mm, vertex order and count kept; :func:`write_mesh` (``write_mesh.py``) writes one back.
- :func:`read_texture_image`, :func:`read_mtl`, :func:`pack_textures` (``mesh_texture.py``): a
  mesh's colour texture (an OBJ's MTL ``map_Kd``, a glTF base colour, a PLY ``TextureFile``),
  several packed into one atlas, as :func:`read_mesh` keeps it in ``Mesh.texture``.
- :func:`read_image` / :func:`write_image` (``image_file.py``): one PNG (8/16-bit), JPEG, TIFF or
  EXR image as stored (footage frames, maps, textures).
- :func:`read_markers` (``read_markers.py``): a C3D, TRC, Qualisys TSV or
  Motive/facecap CSV take to a :class:`~facecap.MarkerSequence` in mm, NaN in
  gaps; :func:`write_markers` (``write_markers.py``) writes one.
- :func:`read_correspondence` (``read_correspondence.py``): the marker -> scan
  map, and :func:`match_correspondence` to line it up with a take's labels.
- :func:`load_ict_sample`, :func:`bundled_path` (``ict_sample.py``): the files facecap
  ships, the ICT-FaceKit face region (as an :class:`IctSample`) and the AnimFace take,
  read for the demo, the generator, the anatomy's ICT landmarks and the tests.
- ``MESH_FORMATS``, ``MARKER_FORMATS`` and ``MAP_FORMATS``, beside their
  readers: the formats each reads, by suffix; ``facecap --help`` lists them.
- :func:`write_mocap_correspondence` / :func:`read_mocap_correspondence`
  (``mocap_correspondence.py``): a result's ``correspondence.npz``, the map from
  its face back into the capture's frame, where cameras are calibrated.
- ``result_layout.py``: the result folder's layout, in one place: its file names
  (:data:`PERFORMANCE_FILE`, :data:`REST_OBJ_FILE`), the exports
  (:data:`EXPORT_FORMATS`, :data:`STREAMED_FORMATS`, :data:`EXPORT_FRAMES`,
  :data:`WORLD_FRAME_FORMATS`), :func:`parse_export_formats`, the files each
  export writes (:func:`export_files`), the files ``performance.json`` lists
  (:func:`file_sizes`), and :func:`read_performance_info`, which reads it back.
- :class:`PerformanceWriter` (``write_performance.py``): the streamed output
  folder every command writes: the frames, the rig, the metadata, then the
  rename; :func:`check_result_destination` refuses a destination before a job's
  long work. :class:`UsdPerformanceWriter` (``write_usd.py``) is its USD
  export (usd-core is imported only when a USD file is written). The exports
  made from a finished folder and the run's pages are the job's
  (:func:`facecap.pipelines.finish_result`, :func:`facecap.pipelines.export_result`).
- :func:`write_mdd` and :func:`write_pc2` (``write_point_cache.py``): streamed
  MDD and PC2 point caches (Blender's Mesh Cache modifier, 3ds Max's Point
  Cache); :func:`write_alembic` (``write_alembic.py``): a streamed Alembic
  archive (the optional alembic3d is imported only when one is written, by
  :func:`import_alembic`). The checks these streamed writers share are in
  ``frame_blocks.py`` (:func:`check_frame_blocks`, :func:`as_frame_count`,
  :func:`path_with_suffix`); :func:`check_uvs` (``write_mesh.py``) checks the UVs (and :func:`write_texture_files` writes a texture with its MTL)
  a mesh writer writes.
- :func:`write_detail_maps`, :func:`write_maps_index` (``write_detail_maps.py``): the detail's
  per-video-frame displacement (EXR, mm) and normal maps (16-bit PNG) and ``maps/maps.json``.
- :func:`write_gltf` (``write_gltf.py``): a ``.glb`` review file, the mesh in
  metres with morph targets, their weights animation and marker nodes
  (:func:`triangle_corners`: a triangle's corners among the polygons' corners).
- :class:`ResultRig` (``result_rig.py``): the exact compact form of a result
  linear in per-frame coefficients (``rig/``), :func:`write_rig` / :func:`read_rig`
  (:func:`check_frame_range` checks the frames asked of a result);
  :func:`read_result` (``read_result.py``) opens any finished result folder and
  gives its frames lazily from ``vertices.npy`` or the rig;
  :func:`write_usd_blendshapes` (``write_usd_blendshapes.py``): the rig (or the
  principal components its caller computed) as UsdSkel blend shapes, its
  weights in [0, 1] (:func:`to_unit_range`, ``weight_ranges.py``), as the
  glTF review file's are; both USD files bind a textured scan's colour texture, written beside
  them (:func:`bind_colour_texture`, :func:`write_texture_beside`, ``usd_material.py``).
- :func:`write_scan_plan` / :func:`read_scan_plan` (``scan_plan.py``) and
  :func:`write_registered_scans` / :func:`read_registered_scans`
  (``registered_scans.py``): the files of the scan workflow (``plan.json``, the
  bases folder); :func:`write_conditioned_take` / :func:`read_conditioned_take`
  (``conditioned_take.py``): the take conditioned once by ``plan-scans`` and read
  by the later steps, with :func:`file_sha256` to tell it is the same take.
- :func:`read_region_mask` (``read_region_mask.py``): a region of a mesh's vertices (a JSON
  list of indices or a ``.npy`` bool mask), as ``remove-wrinkles`` reads it.

- :func:`atomic_path`, :func:`atomic_folder`, :func:`atomic_write_text`
  (``atomic_write.py``): how every writer writes (under a hidden name, renamed into
  place when finished), with :func:`check_file_destination`,
  :func:`check_folder_destination`, :func:`ensure_folder`, and the paths a written
  file records (:func:`recorded_path`, :func:`resolve_recorded_path`, :func:`final_path`).

The functions share their modules' names, so ``facecap.io.read_mesh`` is the
function; reach a module itself with ``importlib.import_module``.
"""

from __future__ import annotations

from .atomic_write import (atomic_folder, atomic_path, atomic_write_text, check_file_destination,
                           check_folder_destination, ensure_folder, final_path, recorded_path, resolve_recorded_path)
from ..structures import Correspondence  # the record read_correspondence returns (facecap.structures)
from .read_correspondence import MAP_FORMATS, CorrespondenceMatch, match_correspondence, read_correspondence
from .mocap_correspondence import read_mocap_correspondence, write_mocap_correspondence
from .read_markers import MARKER_FORMATS, MARKER_SUFFIXES, read_markers
from .read_mesh import MESH_FORMATS, MESH_SUFFIXES, read_mesh
from .image_file import IMAGE_SUFFIXES, read_image, write_image
from .mesh_texture import TEXTURE_SUFFIXES, MtlMaterial, pack_textures, read_mtl, read_texture_image
from .conditioned_take import CONDITIONED_TAKE_FORMAT, file_sha256, read_conditioned_take, write_conditioned_take
from .registered_scans import BASES_MARKER_FILE, CONDITIONED_TAKE_FILE, read_registered_scans, write_registered_scans
from .scan_plan import PLAN_FORMAT, read_scan_plan, write_scan_plan
from .write_markers import write_markers
from .write_detail_maps import MAPS_FOLDER, MAPS_INDEX, detail_map_names, write_detail_maps, write_maps_index
from .write_mesh import check_uvs, write_mesh, write_texture_files
from .result_layout import (
    EXPORT_FORMATS,
    EXPORT_FRAMES,
    PERFORMANCE_FILE,
    REST_OBJ_FILE,
    STREAMED_FORMATS,
    WORLD_FRAME_FORMATS,
    export_files,
    file_sizes,
    parse_export_formats,
    read_performance_info,
)
from .write_performance import PerformanceWriter, check_result_destination
from .write_usd import UsdPerformanceWriter
from .frame_blocks import as_frame_count, check_frame_blocks, path_with_suffix
from .write_point_cache import write_mdd, write_pc2
from .write_alembic import import_alembic, write_alembic
from .write_gltf import (MAX_MORPH_TARGETS, MORPH_GPU_BUDGET_BYTES, MORPH_GPU_BYTES_PER_VERTEX_TARGET, triangle_corners,
                         write_gltf)
from .result_rig import RIG_FORMAT, RIG_PRECISIONS, ResultRig, check_frame_range, read_rig, write_rig
from .read_result import MESH_FILE, Result, read_result
from .usd_material import bind_colour_texture, texture_file_beside, write_texture_beside
from .write_usd_blendshapes import (DEFAULT_BLENDSHAPE_TOLERANCE_MM, DEFAULT_USD_COMPONENTS, USD_EXACT_MAX_BYTES,
                                    write_usd_blendshapes)
from .weight_ranges import UnitRangeWeights, to_unit_range
from .read_region_mask import read_region_mask
from .ict_sample import IctSample, bundled_path, load_ict_sample

__all__ = [
    "IMAGE_SUFFIXES",
    "read_image",
    "write_image",
    "TEXTURE_SUFFIXES",
    "MtlMaterial",
    "pack_textures",
    "read_mtl",
    "read_texture_image",
    "MAPS_FOLDER",
    "detail_map_names",
    "write_detail_maps",
    "MAPS_INDEX",
    "write_maps_index",
    "load_ict_sample",
    "bundled_path",
    "IctSample",
    "write_gltf",
    "MAX_MORPH_TARGETS",
    "MORPH_GPU_BUDGET_BYTES",
    "MORPH_GPU_BYTES_PER_VERTEX_TARGET",
    "read_mesh",
    "MESH_FORMATS",
    "MESH_SUFFIXES",
    "write_mesh",
    "read_markers",
    "MARKER_FORMATS",
    "MARKER_SUFFIXES",
    "write_markers",
    "read_correspondence",
    "MAP_FORMATS",
    "match_correspondence",
    "Correspondence",
    "CorrespondenceMatch",
    "read_mocap_correspondence",
    "write_mocap_correspondence",
    "PerformanceWriter",
    "EXPORT_FORMATS",
    "PERFORMANCE_FILE",
    "REST_OBJ_FILE",
    "read_performance_info",
    "UsdPerformanceWriter",
    "write_mdd",
    "write_pc2",
    "write_alembic",
    "import_alembic",
    "check_frame_blocks",
    "as_frame_count",
    "path_with_suffix",
    "check_uvs",
    "write_texture_files",
    "triangle_corners",
    "check_frame_range",
    "STREAMED_FORMATS",
    "file_sizes",
    "check_result_destination",
    "ResultRig",
    "write_rig",
    "read_rig",
    "RIG_FORMAT",
    "RIG_PRECISIONS",
    "read_result",
    "Result",
    "MESH_FILE",
    "write_usd_blendshapes",
    "bind_colour_texture",
    "texture_file_beside",
    "write_texture_beside",
    "DEFAULT_BLENDSHAPE_TOLERANCE_MM",
    "DEFAULT_USD_COMPONENTS",
    "USD_EXACT_MAX_BYTES",
    "to_unit_range",
    "UnitRangeWeights",
    "parse_export_formats",
    "export_files",
    "EXPORT_FRAMES",
    "WORLD_FRAME_FORMATS",
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
    "atomic_folder",
    "atomic_path",
    "atomic_write_text",
    "check_file_destination",
    "check_folder_destination",
    "ensure_folder",
    "final_path",
    "recorded_path",
    "resolve_recorded_path",
    "read_region_mask",
]
