"""Synthetic ground truth: the bundled ICT face sample and generated capture takes."""

from __future__ import annotations

from .expression_curves import EXPRESSION_PRESETS, smooth_expression_curves
from .generate_performance import SyntheticCase, generate_performance
from .ict_sample import IctSample, bundled_path, load_ict_sample
from .marker_layout import animface_marker_map, choose_marker_vertices
from .scan_expression import ScannedExpression, scan_expression
from .write_synthetic_case import CaseFiles, write_planned_scans, write_synthetic_case

__all__ = [
    "EXPRESSION_PRESETS",
    "CaseFiles",
    "IctSample",
    "ScannedExpression",
    "SyntheticCase",
    "animface_marker_map",
    "bundled_path",
    "choose_marker_vertices",
    "generate_performance",
    "load_ict_sample",
    "scan_expression",
    "smooth_expression_curves",
    "write_planned_scans",
    "write_synthetic_case",
]
