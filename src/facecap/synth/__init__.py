"""Synthetic ground truth: the bundled ICT face sample and generated capture takes."""

from __future__ import annotations

from .expression_curves import EXPRESSION_PRESETS, smooth_expression_curves
from .generate_performance import SyntheticCase, generate_performance
from .ict_sample import IctSample, bundled_path, load_ict_sample
from .generate_performance import CURVE_GENERATORS, HEAD_PIVOTS_MM
from .marker_layout import animface_marker_map, choose_marker_vertices
from .real_motion_curves import RealCurveFit, load_real_curve_fit, real_motion_curves
from .scan_expression import ScannedExpression, scan_expression
from .speech_curves import speech_expression_curves
from .write_synthetic_case import CaseFiles, write_planned_scans, write_synthetic_case

__all__ = [
    "CURVE_GENERATORS",
    "HEAD_PIVOTS_MM",
    "RealCurveFit",
    "load_real_curve_fit",
    "real_motion_curves",
    "speech_expression_curves",
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
