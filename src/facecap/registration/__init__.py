"""Registration of markers and scans: rigid ICP and the marker-to-scan registration of Huang et al. (2011)."""

from __future__ import annotations

from .register_markers_to_scan import MarkerRegistration, register_markers_to_scan
from .rigid_icp import IcpResult, rigid_icp

__all__ = ["IcpResult", "MarkerRegistration", "register_markers_to_scan", "rigid_icp"]
