"""Registration of markers and scans: rigid ICP and the marker-to-scan registration of Huang et al. (2011)."""

from __future__ import annotations

from .cylindrical_map import CylindricalMap, TriangleRaster, cylindrical_map
from .refine_registration import Refinement, refine_registration
from .register_markers_to_scan import MarkerRegistration, register_markers_to_scan
from .register_scans import RegisteredScans, register_scans
from .register_template_to_scan import TemplateRegistration, register_template_to_scan
from .rigid_icp import IcpResult, rigid_icp

__all__ = [
    "CylindricalMap",
    "IcpResult",
    "Refinement",
    "TriangleRaster",
    "cylindrical_map",
    "refine_registration",
    "MarkerRegistration",
    "RegisteredScans",
    "TemplateRegistration",
    "register_markers_to_scan",
    "register_scans",
    "register_template_to_scan",
    "rigid_icp",
]
