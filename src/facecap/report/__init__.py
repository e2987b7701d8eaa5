"""Evaluation and reports: dense error against ground truth, file summaries, mesh pictures, plots.

In the order a user meets them:

- :func:`describe_file` (``describe.py``): what a take, a mesh or a result
  folder holds (``facecap info``).
- :func:`evaluate_result`, :func:`read_truth` (``evaluate_result.py``): the
  dense error of an output folder against a ground-truth file (``facecap evaluate``);
  :func:`result_and_truth_mm` gives both aligned, for per-vertex use.
- :func:`evaluate_performance` (``evaluate_performance.py``): the same on
  arrays, as :class:`DenseError` with per-region :class:`RegionError`.
- :func:`render_mesh`, :func:`render_side_by_side` (``render_mesh.py``):
  headless pictures of a mesh, as :class:`MeshPanel` panels.
- :func:`plot_series` (``plot_series.py``): per-frame quantities against time.
- :func:`write_review_page`, :func:`serve`, :class:`ReviewServer` (``review_page.py``):
  the result's GLB played in the browser (three.js, offline), and the localhost server
  of ``facecap view``.
- :func:`write_html_report` (``html_report.py``): one self-contained HTML report per run.
- :func:`view_result`, :func:`write_run_report` (``view_result.py``): what ``facecap view``
  writes into a result folder (the GLB if missing, ``review.html``, ``report.html``).

Imported eagerly (matplotlib is a main dependency): a lazy ``__getattr__`` would
hand out the *module* ``render_mesh`` instead of the function of the same name
once anything had imported ``facecap.report.render_mesh`` directly.
"""

from __future__ import annotations

from .describe import describe_file
from .evaluate_performance import DenseError, RegionError, evaluate_performance
from .evaluate_result import evaluate_result, read_truth, result_and_truth_mm
from .html_report import write_html_report
from .plot_series import plot_series
from .render_mesh import MeshPanel, render_mesh, render_side_by_side
from .review_page import EMBED_LIMIT_BYTES, ReviewServer, serve, write_review_page
from .view_result import ERROR_ROWS, view_result, write_run_report

__all__ = [
    "describe_file",
    "evaluate_result",
    "read_truth",
    "evaluate_performance",
    "DenseError",
    "RegionError",
    "render_mesh",
    "render_side_by_side",
    "MeshPanel",
    "plot_series",
    "write_review_page",
    "serve",
    "ReviewServer",
    "EMBED_LIMIT_BYTES",
    "write_html_report",
    "result_and_truth_mm",
    "view_result",
    "write_run_report",
    "ERROR_ROWS",
]
