"""Evaluation and reports: dense error against ground truth, mesh pictures, time-series plots.

Imported eagerly (matplotlib is a main dependency): a lazy ``__getattr__`` would
hand out the *module* ``render_mesh`` instead of the function of the same name
once anything had imported ``facecap.report.render_mesh`` directly.
"""

from __future__ import annotations

from .evaluate_performance import DenseError, RegionError, evaluate_performance
from .plot_series import plot_series
from .render_mesh import MeshPanel, render_mesh, render_side_by_side

__all__ = [
    "evaluate_performance",
    "DenseError",
    "RegionError",
    "render_mesh",
    "render_side_by_side",
    "MeshPanel",
    "plot_series",
]
