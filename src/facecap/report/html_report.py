"""One HTML file per run: the figures of ``report.json`` and ``performance.json``, plots, pictures.

The report is self-contained: pictures and plots are embedded as base64 PNGs, so the file can be
mailed or archived alone; only the link to the review page is relative (the page lies in the
result folder beside it). The figures are laid out from the JSON as it is, so every stage's
report (``facecap animate``, ``facecap blend``, evaluations) renders without a schema of its own:
top-level numbers form a summary, each top-level group a table, per-frame series a plot
(:func:`~facecap.report.plot_series`), and lists of text (warnings, notes) a list.
"""

from __future__ import annotations

import base64
import datetime
import html
import json
import math
import os
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from ..errors import InputError
from ..io._atomic import atomic_path
from .plot_series import plot_series

__all__ = ["write_html_report"]

_UNIT_SUFFIXES = {"_mm": "mm", "_s": "s", "_deg": "deg", "_pct": "%", "_mm2": "mm²", "_hz": "Hz"}
_INLINE_LIST = 12
"""Lists of numbers up to this long are written out in the table; longer ones are summarised."""
_STYLE = """
body { font: 14px/1.45 system-ui, sans-serif; margin: 24px auto; max-width: 1100px; padding: 0 16px; color: #222; }
h1 { font-size: 22px; margin-bottom: 4px; } h2 { font-size: 17px; margin-top: 28px; border-bottom: 1px solid #ddd; }
.meta { color: #666; } table { border-collapse: collapse; margin: 8px 0; }
td, th { border: 1px solid #ddd; padding: 3px 8px; text-align: left; vertical-align: top; }
td.num { text-align: right; font-variant-numeric: tabular-nums; } th { background: #f4f4f4; }
figure { margin: 12px 0; } figure img { max-width: 100%; border: 1px solid #eee; }
figcaption { color: #555; font-size: 13px; } .review { font-size: 16px; margin: 12px 0; }
ul.notes li { margin: 2px 0; }
"""


def _unit(key: str) -> str:
    for suffix, unit in _UNIT_SUFFIXES.items():
        if key.lower().endswith(suffix):
            return unit
    return ""


def _fmt(value: Any) -> str:
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        x = float(value)
        return "NaN" if math.isnan(x) else f"{x:.4g}"
    return str(value)


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool)


def _numeric_list(value: Any) -> bool:
    return (isinstance(value, (list, tuple)) and len(value) > 0
            and all(_is_number(x) or x is None for x in value) and any(_is_number(x) for x in value))


def _text_list(value: Any) -> bool:
    return isinstance(value, (list, tuple)) and len(value) > 0 and all(isinstance(x, str) for x in value)


def _summary(values: Sequence[Any]) -> str:
    x = np.array([np.nan if v is None else float(v) for v in values])
    finite = x[np.isfinite(x)]
    if finite.size == 0:
        return f"{x.size} values, none finite"
    return (f"{x.size} values: mean {_fmt(finite.mean())}, median {_fmt(float(np.median(finite)))}, "
            f"max {_fmt(finite.max())}")


class _Section:
    """Rows of one table, plus the series to plot and text lists found under it."""

    def __init__(self, title: str) -> None:
        self.title = title
        self.unit = _unit(title)  # a group's unit (marker_residual_mm) holds for its rows without their own
        self.rows: list[tuple[str, str, str]] = []
        self.series: dict[str, list[Any]] = {}
        self.lists: list[tuple[str, list[str]]] = []
        self.records: list[tuple[str, Mapping[str, Any]]] = []

    def add(self, key: str, value: Any, n_frames: int | None) -> None:
        if isinstance(value, Mapping):
            if len(value) >= 2 and all(isinstance(v, Mapping) and v and all(not isinstance(x, (Mapping, list))
                                                                              for x in v.values())
                                       for v in value.values()):
                self.records.append((key, value))  # e.g. per-region figures: one row per region
                return
            if not value:
                self.rows.append((key, "–", ""))
            for sub, v in value.items():
                self.add(f"{key}.{sub}" if key else str(sub), v, n_frames)
        elif _numeric_list(value):
            per_frame = "per_frame" in key or (n_frames is not None and len(value) == n_frames and len(value) > 1)
            if per_frame:
                self.series[key] = list(value)
            if len(value) <= _INLINE_LIST and not per_frame:
                self.rows.append((key, ", ".join(_fmt(v) for v in value), _unit(key) or self.unit))
            else:
                self.rows.append((key, _summary(value), _unit(key) or self.unit))
        elif _text_list(value):
            self.lists.append((key, list(value)))
        elif isinstance(value, (list, tuple)):
            text = json.dumps(value, default=str)
            self.rows.append((key, text if len(text) <= 300 else text[:297] + "...", ""))
        else:
            self.rows.append((key, _fmt(value), _unit(key) or (self.unit if _is_number(value) else "")))


def _table(rows: Sequence[tuple[str, str, str]]) -> str:
    body = "".join(
        f"<tr><th>{html.escape(k)}</th><td class=\"num\">{html.escape(v)}</td><td>{html.escape(u)}</td></tr>"
        for k, v, u in rows)
    return f"<table><tbody>{body}</tbody></table>"


def _records_table(key: str, records: Mapping[str, Mapping[str, Any]]) -> str:
    columns: list[str] = []
    for r in records.values():
        columns += [c for c in r if c not in columns]
    head = "".join(f"<th>{html.escape(c)}</th>" for c in [key, *columns])
    body = "".join(
        "<tr><th>" + html.escape(str(name)) + "</th>"
        + "".join(f"<td class=\"num\">{html.escape(_fmt(r.get(c)))}</td>" for c in columns) + "</tr>"
        for name, r in records.items())
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _data_uri(png: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def _plot(section: _Section, rate: float | None, n_frames: int | None, folder: Path) -> list[tuple[str, bytes]]:
    """One plot per group of equal-length series of a section (matplotlib, via plot_series)."""
    plots = []
    by_length: dict[int, dict[str, list[Any]]] = {}
    for key, values in section.series.items():
        by_length.setdefault(len(values), {})[key] = values
    for length, group in by_length.items():
        if length < 2:
            continue
        timed = rate is not None and (n_frames is None or length == n_frames)
        times = np.arange(length) / rate if timed else np.arange(length, dtype=np.float64)
        units = {_unit(k) or section.unit for k in group}
        unit = units.pop() if len(units) == 1 else ""
        path = folder / f"plot{len(os.listdir(folder))}.png"
        plot_series(times, {k: np.array([np.nan if v is None else float(v) for v in vals])
                            for k, vals in group.items()},
                    path, ylabel=f"{section.title} ({unit})" if unit else section.title,
                    xlabel="time (s)" if timed else "frame", size_px=(1000, 380))
        plots.append((f"{section.title}: " + ", ".join(group), path.read_bytes()))
    return plots


def _plain(value: Any) -> Any:
    """JSON-like Python values from what a caller may pass (numpy arrays and scalars, tuples)."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _read_json(path: Path) -> dict[str, Any] | None:
    if not path.is_file():
        return None
    try:
        value = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"unreadable JSON ({exc})", path=str(path)) from None
    if not isinstance(value, dict):
        raise InputError("expected a JSON object", path=str(path))
    return value


def write_html_report(
    out_html: str | os.PathLike[str],
    result_dir: str | os.PathLike[str],
    *,
    report: Mapping[str, Any] | str | os.PathLike[str] | None = None,
    pictures: Sequence[str | os.PathLike[str]] = (),
    review_page: str | os.PathLike[str] | None = None,
    title: str | None = None,
) -> Path:
    """Write one self-contained HTML report of a run: its figures as tables, plots and pictures.

    Parameters
    ----------
    out_html : str or path-like
        HTML file to write (atomically: a temporary sibling renamed on success).
    result_dir : str or path-like
        The run's result folder; its ``performance.json`` (rate, units, sizes, parameters,
        timings) is read when present.
    report : mapping, str, path-like or None, optional
        The run's report (the content of ``report.json``, or the path of a JSON file); default
        None reads ``result_dir/report.json`` when present.
    pictures : sequence of str or path-like, optional
        PNG pictures of the run, embedded in the report (base64) in this order, captioned by name.
    review_page : str, path-like or None, optional
        The run's review page (:func:`~facecap.report.write_review_page`), linked by its path
        relative to ``out_html``.
    title : str or None, optional
        Heading; default ``'facecap run: <result folder name>'``.

    Returns
    -------
    pathlib.Path
        ``out_html``.

    Raises
    ------
    InputError
        If ``result_dir`` is not a folder, a JSON file is unreadable, or a picture is missing
        or not a PNG.

    Notes
    -----
    Layout: numbers at the top level of the report form the summary; each top-level group a
    table whose rows are its (dotted) keys, a unit taken from the key's suffix (``_mm``,
    ``_s``, ``_deg``, ...); a list of one number per frame (key holding ``per_frame``, or as
    long as the take) is summarised in the table and plotted against time in one plot per
    group; a group of records (such as per-region errors) becomes one table with a row per
    record; lists of text (warnings, notes) are listed.
    """
    result = Path(result_dir)
    if not result.is_dir():
        raise InputError("result folder not found", path=str(result))
    out = Path(out_html)
    if report is None:
        report_data = _read_json(result / "report.json") or {}
    elif isinstance(report, (str, os.PathLike)):
        report_data = _read_json(Path(report))
        if report_data is None:
            raise InputError("report file not found", path=str(report))
    elif isinstance(report, Mapping):
        report_data = _plain(report)
    else:
        raise InputError(f"report: expected a mapping or the path of a JSON file, got {type(report).__name__}")
    performance = _read_json(result / "performance.json") or {}
    images = []
    for p in pictures:
        path = Path(p)
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise InputError(f"cannot read the picture ({exc.strerror or exc})", path=str(path)) from None
        if not data.startswith(b"\x89PNG\r\n\x1a\n"):
            raise InputError("the picture is not a PNG file", path=str(path))
        images.append((path.name, data))

    rate = performance.get("rate", report_data.get("rate"))
    rate = float(rate) if _is_number(rate) and float(rate) > 0 else None
    n_frames = performance.get("n_frames", report_data.get("n_frames"))
    n_frames = int(n_frames) if _is_number(n_frames) else None

    sections: list[_Section] = []
    for source_name, data in (("performance.json", performance), ("report", report_data)):
        top = _Section(f"Summary ({source_name})")
        groups = []
        for key, value in data.items():
            if isinstance(value, Mapping) or _numeric_list(value) and "per_frame" in key:
                group = _Section(key)
                group.add("" if isinstance(value, Mapping) else key, value, n_frames)
                groups.append(group)
            else:
                top.add(key, value, n_frames)
        sections += [top, *groups]

    parts = [f"<h1>{html.escape(title or f'facecap run: {result.resolve().name}')}</h1>",
             f"<p class=\"meta\">{html.escape(str(result))} &middot; written "
             f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC by facecap {__version__}</p>"]
    if review_page is not None:
        href = Path(os.path.relpath(Path(review_page).resolve(), out.resolve().parent)).as_posix()
        parts.append(f"<p class=\"review\"><a id=\"review-link\" href=\"{html.escape(href)}\">"
                     "Open the review page (the animation in 3D)</a></p>")
    with tempfile.TemporaryDirectory(prefix="facecap-report-") as scratch:
        for section in sections:
            if not (section.rows or section.series or section.lists or section.records):
                continue
            parts.append(f"<h2>{html.escape(section.title)}</h2>")
            if section.rows:
                parts.append(_table(section.rows))
            for key, records in section.records:
                parts.append(_records_table(key or section.title, records))
            for key, items in section.lists:
                parts.append(f"<p>{html.escape(key)}:</p><ul class=\"notes\">"
                             + "".join(f"<li>{html.escape(x)}</li>" for x in items) + "</ul>")
            for caption, png in _plot(section, rate, n_frames, Path(scratch)):
                alt = f"plot: {caption}"
                parts.append(f"<figure><img alt=\"{html.escape(alt)}\" src=\"{_data_uri(png)}\">"
                             f"<figcaption>{html.escape(caption)}</figcaption></figure>")
    if images:
        parts.append("<h2>Pictures</h2>")
        for name, png in images:
            parts.append(f"<figure><img alt=\"{html.escape(name)}\" src=\"{_data_uri(png)}\">"
                         f"<figcaption>{html.escape(name)}</figcaption></figure>")
    page = ("<!doctype html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<link rel=\"icon\" href=\"data:,\">\n"
            f"<title>{html.escape(title or result.resolve().name)}</title>\n<style>{_STYLE}</style>\n</head>\n"
            "<body>\n" + "\n".join(parts) + "\n</body>\n</html>\n")
    with atomic_path(out) as tmp:
        tmp.write_text(page, encoding="utf-8")
    return out
