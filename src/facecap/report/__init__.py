"""Evaluation and reports: dense error against ground truth, file summaries, mesh pictures, plots.

In the order a user meets them:

- :func:`describe_file` (``describe.py``): what a take, a mesh or a result
  folder holds (``facecap info``); :func:`format_description` writes it as text.
- :func:`evaluate_result`, :func:`read_truth` (``evaluate_result.py``): the
  dense error of an output folder against a ground-truth file (``facecap evaluate``);
  :func:`result_and_truth_mm` gives both aligned, for per-vertex use.
- :func:`evaluate_performance` (``evaluate_performance.py``): the same on
  arrays, as :class:`DenseError` with per-region :class:`RegionError`.
- :func:`render_mesh`, :func:`render_side_by_side` (``render_mesh.py``):
  headless pictures of a mesh, as :class:`MeshPanel` panels; :func:`draw_mesh` draws one into
  an axes for pictures that mark things on it; :func:`as_size_px` checks every picture's size.
- :func:`plot_marker_map` (``plot_marker_map.py``): a scan with the places ``facecap map`` found
  for the markers, labelled, the ones to check in another colour.
- :func:`plot_series` (``plot_series.py``): per-frame quantities against time;
  :func:`draw_series` draws them into an axes of another picture.
- :func:`plot_scan_selection` (``plot_scan_selection.py``): a scan plan's error per added
  scan (Huang et al. 2011, Fig. 8) and its chosen frames over the take.
- :func:`plot_activations` (``plot_activations.py``): muscle activations over a take, with
  the frames the solve flagged and the marker residual that flagged them.
- :func:`draw_light_check` (``draw_light_check.py``): what ``facecap calibrate-light`` found in
  each camera's image (the sphere's outline, the fitted sphere, the highlight).
- :func:`write_review_page`, :func:`serve`, :class:`ReviewServer` (``review_page.py``):
  the result's GLB played in the browser (three.js, offline), and the localhost server
  of ``facecap view``.
- :func:`write_html_report` (``html_report.py``): one self-contained HTML report per run
  (summary, quality figures explained, warnings explained, details); :func:`explain_warning`
  (``explain_warning.py``) says what each warning means and what to do.
- :func:`write_run_report` (``write_run_report.py``): a result folder's ``report.html``, which
  every job writes at its end and ``facecap view`` (:func:`facecap.pipelines.view_result`) rewrites.

Imported eagerly (matplotlib is a main dependency): a lazy ``__getattr__`` would
hand out the *module* ``render_mesh`` instead of the function of the same name
once anything had imported ``facecap.report.render_mesh`` directly.
"""

from __future__ import annotations

from .describe import describe_file, format_description
from .draw_light_check import draw_light_check
from .evaluate_performance import DenseError, RegionError, evaluate_performance
from .evaluate_result import evaluate_result, read_truth, result_and_truth_mm
from .explain_warning import WarningAdvice, explain_warning
from .html_report import write_html_report
from .plot_activations import plot_activations
from .plot_scan_selection import plot_scan_selection
from .plot_series import draw_series, plot_series
from .plot_marker_map import MARKER_MAP_COLORS, plot_marker_map
from .render_mesh import MeshPanel, as_size_px, draw_mesh, render_mesh, render_side_by_side
from .review_page import EMBED_LIMIT_BYTES, ReviewServer, serve, write_review_page
from .write_run_report import write_run_report

__all__ = [
    "draw_light_check",
    "describe_file",
    "format_description",
    "evaluate_result",
    "read_truth",
    "evaluate_performance",
    "DenseError",
    "RegionError",
    "render_mesh",
    "render_side_by_side",
    "draw_mesh",
    "as_size_px",
    "plot_marker_map",
    "MARKER_MAP_COLORS",
    "MeshPanel",
    "plot_series",
    "draw_series",
    "plot_scan_selection",
    "plot_activations",
    "write_review_page",
    "serve",
    "ReviewServer",
    "EMBED_LIMIT_BYTES",
    "write_html_report",
    "explain_warning",
    "WarningAdvice",
    "result_and_truth_mm",
    "write_run_report",
]
