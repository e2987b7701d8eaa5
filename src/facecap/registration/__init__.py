"""Registration of markers and scans: rigid ICP and the scan registration of Huang et al. (2011).

In the order a user meets them:

- :func:`register_scans` (``register_scans.py``): every scan of a plan in one
  template topology (markers, large scale, fine scale, fitted bases), as
  :class:`RegisteredScans`.
- :func:`fit_bases_to_markers` (``fit_bases_to_markers.py``): registered scans
  deformed to match their frame's markers exactly (section 7), the last step of
  :func:`register_scans`; :func:`smooth_marker_changes` (``smooth_marker_changes.py``), as
  :class:`SmoothedChanges`: what of the markers' disagreement with a basis is smooth beyond their
  noise (a Gaussian process by likelihood), what that fit moves with colour alignment;
  :func:`marker_places_from_bases` (``marker_places_from_bases.py``), as :class:`MarkerPlaces`: each
  marker's place on the template from the colour-aligned bases' material (their median).
- :func:`register_markers_to_scan` (``register_markers_to_scan.py``): one
  frame's markers onto a scan, as a :class:`MarkerRegistration`.
- :func:`register_template_to_scan` (``register_template_to_scan.py``): the
  large-scale template registration of section 6.1, as a :class:`TemplateRegistration`;
  :func:`register_template_to_scans` for several scans of one template, what they share built once.
- :func:`align_albedo` (``align_albedo.py``): a registered template slid along
  its scan until the skin's colours match the template's (tangential
  correspondence from texture), as an :class:`AlbedoAlignment`.
- :func:`refine_registration` (``refine_registration.py``): the fine-scale
  optical-flow registration of section 6.2, as a :class:`Refinement`, on the
  :func:`cylindrical_map` (``cylindrical_map.py``) unwrap. The parts it shares with
  :func:`align_albedo`: :func:`optical_flow` (``optical_flow.py``), OpenCV's dense flow
  between two feature images; :func:`visible_in_raster` (``visible_in_raster.py``), the
  vertices an unwrap's image shows; :func:`regularised_update` (``regularised_update.py``),
  eq. 11: a mesh moved by a displacement field, Laplacian-regularised, back onto its scan
  without flipped triangles.
- :func:`rigid_icp` (``rigid_icp.py``): rigid ICP of points onto a surface, as
  an :class:`IcpResult`; :func:`rigid_icp_to_surface` runs it on a
  :class:`ClosestPointSurface` built once; :func:`trimmed_inliers` picks a step's inliers and
  :func:`check_surface_units` refuses a surface in other units than the points.
- :func:`find_marker_map` (``find_marker_map.py``): where each marker of a take
  sits on a scan, found by a global search from the rest frame, as a :class:`MarkerMap`;
  :func:`marker_status` names each marker's outcome. :func:`rest_markers_of`
  (``rest_markers_of.py``) prepares the take's rest frame and motion for it. ``facecap map``'s
  job, the map written as ``map.json`` with its report and picture, is
  :func:`facecap.pipelines.map_markers`.
- :func:`check_marker_map` (``check_marker_map.py``): ``facecap info map.json
  --scan --markers``, a hand-made map checked against the take, as a dict.

The functions share their modules' names, so
``facecap.registration.register_scans`` is the function; reach a module itself
with ``importlib.import_module``.
"""

from __future__ import annotations

from .align_albedo import DEFAULT_ALBEDO_ITERATIONS, SEAM_WELD_MM, UNSEEN_ANCHOR, AlbedoAlignment, align_albedo
from .fit_bases_to_markers import fit_bases_to_markers
from .smooth_marker_changes import SmoothedChanges, smooth_marker_changes
from .marker_places_from_bases import MarkerPlaces, marker_places_from_bases
from .cylindrical_map import CylindricalMap, TriangleRaster, cylindrical_map
from .optical_flow import optical_flow
from .refine_registration import Refinement, refine_registration
from .regularised_update import regularised_update
from .visible_in_raster import visible_in_raster
from .register_markers_to_scan import MIN_FACING_OUTWARD, MarkerRegistration, register_markers_to_scan, scan_winding
from .register_scans import (
    DEFAULT_REST_WEIGHT,
    TEMPLATE_DEFORMATION_WEIGHT,
    RegisteredScans,
    default_workers,
    register_scans,
)
from .register_template_to_scan import (DEFAULT_CLOSEST_POINT_WEIGHTS, TemplateRegistration, register_template_to_scan,
                                        register_template_to_scans)
from .rigid_icp import (ClosestPointSurface, IcpResult, check_surface_units, rigid_icp, rigid_icp_to_surface,
                        trimmed_inliers)
from .find_marker_map import (
    ALONG_SKIN_FLOOR_MM,
    ALONG_SKIN_PER_HEIGHT,
    DEFAULT_AMBIGUITY_MM,
    DEFAULT_OFF_SKIN_MM,
    DEFAULT_UNCERTAIN_MM,
    MIN_MAP_MARKERS,
    UNSURE_SCORE_RATIO,
    MarkerMap,
    find_marker_map,
    marker_status,
)
from .rest_markers_of import MAX_MOTION_FRAMES, rest_markers_of
from .check_marker_map import MAP_CHECK_MM, check_marker_map

__all__ = [
    "fit_bases_to_markers",
    "SmoothedChanges",
    "smooth_marker_changes",
    "MarkerPlaces",
    "marker_places_from_bases",
    "align_albedo",
    "AlbedoAlignment",
    "DEFAULT_ALBEDO_ITERATIONS",
    "UNSEEN_ANCHOR",
    "SEAM_WELD_MM",
    "register_scans",
    "default_workers",
    "RegisteredScans",
    "DEFAULT_REST_WEIGHT",
    "TEMPLATE_DEFORMATION_WEIGHT",
    "register_markers_to_scan",
    "MarkerRegistration",
    "MIN_FACING_OUTWARD",
    "scan_winding",
    "register_template_to_scan",
    "register_template_to_scans",
    "TemplateRegistration",
    "DEFAULT_CLOSEST_POINT_WEIGHTS",
    "refine_registration",
    "Refinement",
    "optical_flow",
    "visible_in_raster",
    "regularised_update",
    "cylindrical_map",
    "CylindricalMap",
    "TriangleRaster",
    "rigid_icp",
    "IcpResult",
    "rigid_icp_to_surface",
    "check_surface_units",
    "trimmed_inliers",
    "ClosestPointSurface",
    "find_marker_map",
    "MarkerMap",
    "MIN_MAP_MARKERS",
    "DEFAULT_OFF_SKIN_MM",
    "DEFAULT_AMBIGUITY_MM",
    "DEFAULT_UNCERTAIN_MM",
    "ALONG_SKIN_FLOOR_MM",
    "ALONG_SKIN_PER_HEIGHT",
    "UNSURE_SCORE_RATIO",
    "marker_status",
    "rest_markers_of",
    "MAX_MOTION_FRAMES",
    "check_marker_map",
    "MAP_CHECK_MM",
]
