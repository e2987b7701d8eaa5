"""``report.html`` of a result folder: the page every job writes at its end and ``facecap view`` rewrites."""

from __future__ import annotations

import os
from pathlib import Path

from ..io.read_result import Result, read_result
from .html_report import write_html_report

__all__ = ["write_run_report"]


def write_run_report(result: Result | str | os.PathLike[str], *, drawn_plots: dict[bytes, bytes] | None = None) -> Path:
    """``report.html`` of a result folder: its figures, plots and pictures, linking ``review.html`` if present.

    ``drawn_plots``: as for :func:`~facecap.report.write_html_report` (plots shared by the pages of one run).
    """
    result = result if isinstance(result, Result) else read_result(result)
    pictures = sorted(result.path.glob("*.png")) + sorted(result.path.glob("pictures/*.png"))
    review = result.path / "review.html"
    return write_html_report(result.path / "report.html", result.path, pictures=pictures,
                             review_page=review if review.is_file() else None, drawn_plots=drawn_plots)
