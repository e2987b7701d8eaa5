"""One HTML report per run, for the person who checks a capture: what ran, how good it is, what to look at.

A capture TD reads it in a minute, top to bottom. Each part appears only where the run's files
hold its data (a folder written by an older facecap lacks newer figures: that part is left out,
never an error):

1. **Summary**: the command and its method, the inputs, frames x vertices, markers, rate and
   length, the unit of the written files, the time the run took, the head motion and the rest
   pose in a line each, and how many warnings there are.
2. **Quality**: each figure the run measured (``report.json``; ``blend_report.json`` of
   ``facecap blend``; ``wrinkles.json`` of ``facecap wrinkles``), with its value and unit, what it
   means and what a good value is, and a plot against the frame where it varies per frame.
   Figures that need a look are marked.
3. **Warnings**: each with what it means and what to do (:func:`~facecap.report.explain_warning`),
   then the run's notes.
4. **Pictures** the run made.
5. **Details**: the timings (once), the files with their sizes (kB, MB, GB in powers of 1000, as
   file browsers show them), the parameters, the inputs with full paths, the exports, the
   per-marker table (collapsed on screen, open in print), the mesh check, and any other figure
   the report holds, under a readable name rather than its key.

Frame numbers are the take's: the first frame is ``report.json``'s ``first_frame`` (the muscle
solve's first solved frame) or else ``performance.json``'s (the take's first frame number).
The page is self-contained: plots and pictures are embedded PNGs, there is no script, and the
only address in it is the relative link to the review page beside it.
"""

from __future__ import annotations

import base64
import datetime
import hashlib
import html
import json
import math
import os
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from ..errors import InputError
from ..io.atomic_write import atomic_path, final_path
from ..io.result_layout import file_sizes
from .explain_warning import explain_warning
from .plot_series import plot_series

__all__ = ["write_html_report"]

_STYLE = """
body { font: 15px/1.5 system-ui, sans-serif; margin: 24px auto; max-width: 960px; padding: 0 16px; color: #222; }
h1 { font-size: 24px; margin: 0 0 2px; } h2 { font-size: 19px; margin: 30px 0 8px; border-bottom: 2px solid #ddd; }
h3 { font-size: 16px; margin: 0 0 4px; } .meta { color: #666; margin: 0 0 12px; }
table { border-collapse: collapse; margin: 6px 0 12px; }
th, td { border-bottom: 1px solid #e4e4e4; padding: 3px 12px 3px 0; text-align: left; vertical-align: top; }
th { font-weight: 600; color: #444; white-space: nowrap; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
table.summary th { width: 150px; } table.summary td { font-size: 16px; }
.block { border-left: 4px solid #9bc29b; padding: 4px 0 4px 12px; margin: 14px 0; }
.block.look { border-left-color: #e0a030; } .tag { font-size: 12px; font-weight: 600; color: #7a4f00;
  background: #fbe7bf; border-radius: 3px; padding: 1px 6px; margin-left: 8px; vertical-align: 2px; }
.value { font-size: 17px; margin: 2px 0; } .about { margin: 2px 0; color: #333; } .good { margin: 2px 0; color: #555; }
.warning { border-left: 4px solid #d9534f; padding: 4px 0 4px 12px; margin: 12px 0; }
.warning .message { font-family: ui-monospace, monospace; font-size: 13px; margin: 0 0 4px; overflow-wrap: anywhere; }
.warning p { margin: 2px 0; } ul.notes li { margin: 2px 0; }
figure { margin: 8px 0; } figure img { max-width: 100%; border: 1px solid #eee; }
figcaption { color: #555; font-size: 13px; } .review { font-size: 16px; margin: 8px 0 0; }
details { margin: 8px 0; } summary { cursor: pointer; font-weight: 600; }
.path { font-family: ui-monospace, monospace; font-size: 13px; overflow-wrap: anywhere; }
@media print {
  body { max-width: none; margin: 0; font-size: 12px; } a.review-link { display: none; }
  .block, .warning, figure, tr { break-inside: avoid; } h2 { break-after: avoid; }
  details::details-content { content-visibility: visible; display: contents; }
  details > summary { list-style: none; }
}
"""

_COMMANDS = {
    "bickel2007-large-scale": ("facecap animate", "the scan deformed by the markers through a thin shell "
                               "(Bickel et al. 2007, large scale)"),
    "huang2011-blendshapes": ("facecap blend", "each frame rebuilt as a blend of registered scans of the take's "
                              "expressions (Huang et al. 2011)"),
    "sifakis2005-muscle-activations": ("facecap solve-muscles", "muscle activations and jaw solved in a simulated "
                                       "face so that its skin follows the markers (Sifakis et al. 2005)"),
    "sifakis2005-muscle-edit": ("facecap edit-muscles", "frames of a muscle result simulated again with edited "
                                "controls"),
    "bickel2007-medium-scale": ("facecap wrinkles", "wrinkles tracked in footage added to a large-scale result "
                                "(Bickel et al. 2007, medium scale)"),
}
"""``performance.json``'s ``method``: the command that writes it and what it does."""

_INPUTS = {"scan": "Scan", "markers": "Take", "map": "Marker map", "model": "Muscle model", "bases": "Scan bases",
           "result": "Edited result", "large_scale": "Large-scale result", "footage": "Footage"}

_UNIT_SUFFIXES = (("_mn_per_mm", "mN/mm"), ("_mm2", "mm²"), ("_mm", "mm"), ("_deg", "°"), ("_hz", "Hz"),
                  ("_pct", "%"), ("_mn", "mN"), ("_px", "px"), ("_s", "s"))
"""Key suffixes naming a value's unit, longest first."""

_LABELS = {
    "ks": "stretching stiffness (ks)", "kb_mm2": "bending stiffness (kb)", "smooth": "markers filtered",
    "temporal_sigma_s": "filter width in time (sigma)", "unmarked_pieces": "scan pieces without markers",
    "marker_offset_mm": "marker offset from the skin", "offset_iterations": "marker offset iterations",
    "rest_average_s": "rest frame averaged over", "stable_markers": "stable markers (head)",
    "backend": "sparse solver", "precision": "precision of the per-frame product",
    "product_error_bound_mm": "error bound of that precision", "chunk_frames": "frames per chunk",
    "model_sha256": "muscle model (SHA-256)", "retarget": "take carried onto the scan by (option)",
    "frames_per_second": "frames per second", "total_s": "total", "rms_mm": "RMS", "max_mm": "largest",
    "mean_mm": "mean", "depth_scale": "wrinkle depth scale",
    "video_rate_hz": "video rate", "first_mocap_frame": "first mocap frame of the video",
    "weights_s": "blend weights", "usd": "USD", "gltf": "glTF", "mdd": "MDD", "pc2": "PC2", "abc": "Alembic",
    "obj": "OBJ", "ply": "PLY",
}
"""Readable names of keys whose plain words would say too little."""

_MUSCLE_FLAGS = {
    "too_few_markers": "too few markers seen to solve: the previous frame's muscles are carried",
    "inverted_tets": "some tetrahedra of the simulated flesh turned inside out",
    "not_converged": "a simulation step did not reach its tolerance",
    "constraint_violation": "the solved controls break a limit (activation range, bone rigidity, jaw joint)",
    "jaw_at_limit": "the jaw at the end of its range: the markers ask for more than the joint allows",
    "large_residual": "a marker farther from the simulated skin than the flag threshold (5 mm by default)",
}
"""What each muscle-solve frame flag (:data:`facecap.muscles.FRAME_FLAGS`) means."""

_PICTURES = {
    "activations.png": "Muscle activations over the solved frames (0 relaxed, 1 fully contracted): the most active "
                       "muscles by name, the others as a band.",
}

_PLOT_SIZE_PX = (900, 280)


# --------------------------------------------------------------------------------------------------- values

def _get(data: Any, *path: str) -> Any:
    """``data[path[0]][path[1]]...``, or None where a key is missing or a level is not a mapping."""
    for key in path:
        if not isinstance(data, Mapping):
            return None
        data = data.get(key)
    return data


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_))


def _float(x: Any) -> float | None:
    """A finite number as float, else None."""
    return float(x) if _is_number(x) and math.isfinite(float(x)) else None


def _series(x: Any) -> np.ndarray | None:
    """A non-empty list of numbers (None for gaps) as a float array with NaN gaps; (T,) or (T, M)."""
    if not isinstance(x, (list, tuple)) or not x:
        return None
    try:
        a = np.array([[np.nan if v is None else v for v in row] if isinstance(row, (list, tuple))
                      else (np.nan if row is None else row) for row in x], dtype=np.float64)
    except (TypeError, ValueError):
        return None
    if a.ndim not in (1, 2) or a.size == 0:
        return None
    a[~np.isfinite(a)] = np.nan
    return a if np.isfinite(a).any() else None


def _texts(x: Any) -> list[str]:
    return [str(v) for v in x] if isinstance(x, (list, tuple)) else []


def _number(x: Any) -> str:
    """A number as a TD reads it: integers with thousands separators, three significant digits otherwise."""
    if isinstance(x, (bool, np.bool_)):
        return "yes" if x else "no"
    if isinstance(x, (int, np.integer)):
        return f"{int(x):,}"
    v = float(x)
    if not math.isfinite(v):
        return "–"
    a = abs(v)
    if a == 0:
        return "0"
    if a >= 100:
        return f"{v:,.0f}"
    if a >= 0.001:
        return f"{v:.3g}"
    if a >= 0.0001:
        return f"{v:.2g}"
    return f"{v:.1e}"


def _quantity(x: Any, unit: str) -> str:
    text = _number(x)
    if not unit or text == "–":
        return text
    return f"{text}{unit}" if unit == "°" else f"{text} {unit}"


def _duration(seconds: float) -> str:
    if seconds < 60:
        return _quantity(seconds, "s")
    minutes, s = divmod(round(seconds), 60)
    if minutes < 60:
        return f"{minutes} min {s:02d} s"
    return f"{minutes // 60} h {minutes % 60:02d} min"


def _size(n_bytes: int) -> str:
    """A file size in B, kB, MB or GB (powers of 1000, as file browsers show them)."""
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n_bytes >= scale:
            return f"{n_bytes / scale:.3g} {unit}" if n_bytes / scale < 100 else f"{n_bytes / scale:,.0f} {unit}"
    return f"{n_bytes} B"


def _split_unit(key: str) -> tuple[str, str]:
    for suffix, unit in _UNIT_SUFFIXES:
        if key.lower().endswith(suffix) and len(key) > len(suffix):
            return key[: -len(suffix)], unit
    return key, ""


def _label(key: str) -> str:
    """A key as words: ``marker_residual_mm`` -> ``Marker residual``, ``n_boundary_loops`` -> ``Boundary loops``."""
    if key in _LABELS:
        text = _LABELS[key]
    else:
        name, _ = _split_unit(key)
        words = [{"rms": "RMS", "max": "largest", "gpu": "GPU"}.get(w, w) for w in name.replace(".", " ").split("_")
                 if w]
        if len(words) > 1 and words[0] == "n":
            words = words[1:]
        text = " ".join(words) or key
    return text if text.startswith("glTF") else text[:1].upper() + text[1:]


def _in_sentence(label: str) -> str:
    """A label inside a phrase: its first letter lower case, unless it starts an acronym (RMS, USD, GPU)."""
    return label if label[1:2].isupper() or label.startswith("glTF") else label[:1].lower() + label[1:]


def _listed(items: Sequence[str], limit: int = 12) -> str:
    items = list(items)
    if len(items) <= limit:
        return ", ".join(items)
    return ", ".join(items[:limit]) + f" and {len(items) - limit} more"


def _value(key: str, value: Any) -> str:
    """Any JSON value as short text, with the unit its key names."""
    unit = _split_unit(key)[1]
    if value is None:
        return "–"
    if key.endswith("bytes") and _is_number(value):
        return _size(int(value))
    if isinstance(value, Mapping) and not value:
        return "none"
    if _is_number(value) or isinstance(value, (bool, np.bool_)):
        return _quantity(value, unit)
    if isinstance(value, str):
        return value
    series = _series(value) if isinstance(value, (list, tuple)) and all(
        _is_number(v) or v is None for v in value) else None
    if series is not None:
        if series.size <= 8:
            return ", ".join(_number(v) for v in series) + (f" {unit}" if unit else "")
        finite = series[np.isfinite(series)]
        return (f"{series.size:,} values: median {_quantity(float(np.median(finite)), unit)}, "
                f"largest {_quantity(float(finite.max()), unit)}")
    if isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value):
        return _listed(value) if value else "none"
    text = json.dumps(value, default=str)
    return text if len(text) <= 200 else text[:197] + "..."


def _rows(data: Mapping[str, Any], prefix: str = "") -> list[tuple[str, str]]:
    """(label, text) rows of a mapping, nested mappings flattened as 'group: key'."""
    rows = []
    for key, value in data.items():
        label = prefix + (_in_sentence(_label(str(key))) if prefix else _label(str(key)))
        if isinstance(value, Mapping) and value:
            rows += _rows(value, f"{label}: ")
        else:
            rows.append((label, _value(str(key), value)))
    return rows


# --------------------------------------------------------------------------------------------------- HTML

def _e(text: Any) -> str:
    return html.escape(str(text))


def _table(rows: Sequence[tuple[str, str]], *, css: str = "") -> str:
    body = "".join(f"<tr><th>{_e(k)}</th><td>{_e(v)}</td></tr>" for k, v in rows)
    return f"<table class=\"{css}\"><tbody>{body}</tbody></table>" if rows else ""


def _grid(head: Sequence[str], rows: Sequence[Sequence[str]], numeric: Sequence[bool], *, css: str = "") -> str:
    th = "".join(f"<th>{_e(h)}</th>" for h in head)
    body = "".join("<tr>" + "".join(f"<td class=\"num\">{_e(c)}</td>" if num else f"<td>{_e(c)}</td>"
                                     for c, num in zip(row, numeric)) + "</tr>" for row in rows)
    return f"<table class=\"{css}\"><thead><tr>{th}</tr></thead><tbody>{body}</tbody></table>"


def _data_uri(png: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


@dataclass
class _Block:
    """One quality figure: its value, what it means, what is good, a plot, and whether it needs a look."""

    title: str
    value: str
    about: str
    good: str = ""
    plot: str = ""
    look: bool = False
    extra: str = ""

    def html(self) -> str:
        tag = "<span class=\"tag\">look at this</span>" if self.look else ""
        good = f"<p class=\"good\">{_e(self.good)}</p>" if self.good else ""
        return (f"<div class=\"block{' look' if self.look else ''}\"><h3>{_e(self.title)}{tag}</h3>"
                f"<p class=\"value\">{_e(self.value)}</p><p class=\"about\">{_e(self.about)}</p>{self.extra}"
                f"{good}{self.plot}</div>")


class _Plotter:
    """Plots of per-frame figures against the take's frame numbers, embedded as PNG.

    With ``drawn``, a dict shared by the pages of one run, a plot is drawn once: kept there by what
    it shows (the curves' values and labels), it is reused by a page written again from the same
    figures (see :func:`write_html_report`'s ``drawn_plots``).
    """

    def __init__(self, scratch: Path, first_frame: int, drawn: dict[bytes, bytes] | None = None) -> None:
        self.scratch = scratch
        self.first_frame = first_frame
        self.drawn = {} if drawn is None else drawn
        self.count = 0

    def __call__(self, series: Mapping[str, np.ndarray | None], *, ylabel: str, caption: str) -> str:
        curves = {k: v for k, v in series.items() if v is not None}
        lengths = {v.shape[0] for v in curves.values()}
        if not curves or len(lengths) != 1 or lengths.pop() < 2:
            return ""
        T = next(iter(curves.values())).shape[0]
        key = hashlib.blake2b(repr((ylabel, self.first_frame, _PLOT_SIZE_PX,
                                    [(k, v.shape, str(v.dtype)) for k, v in curves.items()])).encode())
        for v in curves.values():
            key.update(np.ascontiguousarray(v).tobytes())
        png = self.drawn.get(key.digest())
        if png is None:
            self.count += 1
            path = self.scratch / f"plot{self.count}.png"
            plot_series(self.first_frame + np.arange(T), curves, path, ylabel=ylabel, xlabel="frame",
                        size_px=_PLOT_SIZE_PX)
            png = self.drawn[key.digest()] = path.read_bytes()
        return (f"<figure><img alt=\"plot: {_e(caption)}\" src=\"{_data_uri(png)}\">"
                f"<figcaption>{_e(caption)}</figcaption></figure>")


# --------------------------------------------------------------------------------------------------- the run

@dataclass
class _Run:
    """What the report is made of: the run's JSON files and its folder's files."""

    shown: Path
    performance: dict[str, Any]
    report: dict[str, Any]
    wrinkles: dict[str, Any]
    files: dict[str, int]
    used: set[str] = field(default_factory=set)
    """Top-level keys of ``report`` rendered by a named part (the rest go to 'Other figures')."""

    @property
    def command(self) -> tuple[str, str] | None:
        method = self.performance.get("method")
        return _COMMANDS.get(method, (str(method), "")) if isinstance(method, str) else None

    @property
    def method(self) -> str | None:
        method = self.performance.get("method")
        return method if isinstance(method, str) else None

    def number(self, key: str) -> float | None:
        """A top-level figure of the report, else of ``performance.json``."""
        value = _float(self.report.get(key))
        return value if value is not None else _float(self.performance.get(key))

    @property
    def rate(self) -> float | None:
        rate = self.number("rate")
        return rate if rate is not None and rate > 0 else None

    @property
    def first_frame(self) -> int:
        first = _float(self.report.get("first_frame"))
        if first is None:
            first = _float(self.performance.get("first_frame"))
        return int(first) if first is not None else 0

    def take(self, *keys: str) -> Any:
        """A top-level entry of the report, marked as rendered."""
        self.used.update(keys)
        return self.report.get(keys[0])

    @property
    def warnings(self) -> list[str]:
        found = _texts(self.report.get("warnings")) + _texts(_get(self.report, "head_motion", "warnings"))
        return list(dict.fromkeys(found))

    @property
    def marker_labels(self) -> list[str]:
        return _texts(self.performance.get("markers")) or _texts(_get(self.report, "marker_residual_mm", "labels"))


# --------------------------------------------------------------------------------------------------- summary

def _file_names(value: Any) -> list[str]:
    paths = value if isinstance(value, (list, tuple)) else [value]
    return [(Path(str(p)).name or str(p)) if "/" in str(p) or os.sep in str(p) else str(p)
            for p in paths if p not in (None, "")]


def _rest_pose_phrase(rest_pose: Mapping[str, Any], rest_frame: Any) -> str:
    frame = f"rest frame {int(rest_frame)}" if _is_number(rest_frame) else "the rest frame"
    mode = rest_pose.get("mode") if isinstance(rest_pose.get("mode"), str) else ""
    text = {"scan": f"{frame} taken to show the scan's expression",
            "expression": f"{frame} holds an expression of its own, kept as motion",
            "neutral_reference": "the scan's expression taken from the neutral reference given"}.get(
        mode, f"{frame}, mode {mode}" if mode else frame)
    chosen_by = rest_pose.get("chosen_by") if isinstance(rest_pose.get("chosen_by"), str) else ""
    chosen = {"auto": "chosen automatically", "option": "chosen by option"}.get(chosen_by)
    reason = rest_pose.get("reason") if isinstance(rest_pose.get("reason"), str) else ""
    if chosen or reason:
        text += " (" + ": ".join(x for x in (chosen, reason) if x) + ")"
    return text


def _head_motion_phrase(run: _Run) -> str | None:
    head = run.report.get("head_motion")
    if isinstance(head, Mapping):
        rotation, translation = _float(head.get("max_rotation_deg")), _float(head.get("max_translation_mm"))
        if head.get("stabilized") is True:
            text = "found and removed"
            source = head.get("pose_from") if isinstance(head.get("pose_from"), str) else None
            stable = _texts(head.get("stable_markers"))
            if source or stable:
                text += " (from " + (source or "") + (": " if source and stable else "") + _listed(stable, 6) + ")"
            if rotation is not None and translation is not None:
                text += f": up to {_quantity(rotation, '°')} and {_quantity(translation, 'mm')}"
            return text
        if head.get("mode") == "off":
            return "not looked for (stabilisation off): any head motion stays in the face's animation"
        return "none found: the take is used as captured"
    stabilized = run.performance.get("stabilized")
    if stabilized is True:
        stable = _texts(_get(run.performance, "parameters", "stable_markers"))
        return "removed" + (f" (rigid set: {_listed(stable, 6)})" if stable else "")
    if stabilized is False:
        return "not removed: any head motion stays in the face's animation"
    return None


def _summary(run: _Run) -> str:
    perf, rep = run.performance, run.report
    rows: list[tuple[str, str]] = []
    if run.command:
        name, what = run.command
        rows.append(("Command", f"{name}: {what}" if what else name))
    sources = perf.get("source_files") if isinstance(perf.get("source_files"), Mapping) else {}
    units = perf.get("source_units") if isinstance(perf.get("source_units"), Mapping) else {}
    rest_frame = rep.get("rest_frame", perf.get("rest_frame"))
    inputs = dict(sources)
    for key in ("map", "large_scale", "footage"):
        if key not in inputs and perf.get(key):
            inputs[key] = perf[key]
    for key, value in inputs.items():
        names = _file_names(value)
        if not names:
            continue
        text = _listed(names, 4)
        if isinstance(units.get(key), str):
            text += f" ({units[key]})"
        if key == "markers" and _is_number(rest_frame):
            text += f", rest frame {int(rest_frame)}"
        if key == "model" and _float(rep.get("n_tets")) is not None:
            text += f", {int(rep['n_tets']):,} tetrahedra"
            if _float(rep.get("n_muscles")) is not None:
                text += f" and {int(rep['n_muscles'])} muscles"
        if key == "footage" and _texts(perf.get("cameras")):
            text = f"{len(_texts(perf['cameras']))} cameras ({_listed(_texts(perf['cameras']), 6)})"
            if _float(perf.get("video_rate_hz")) is not None:
                text += f", video at {_quantity(perf['video_rate_hz'], 'Hz')}"
        rows.append((_INPUTS.get(key, _label(key)), text))
    n_frames, n_vertices = run.number("n_frames"), run.number("n_vertices")
    if n_frames is not None:
        T = int(n_frames)
        text = f"{T:,} frames" + (f" × {int(n_vertices):,} vertices" if n_vertices is not None else "")
        if T > 1:
            text += f" (frames {run.first_frame}–{run.first_frame + T - 1} of the take)"
        rows.append(("Frames", text))
    n_markers = run.number("n_markers")
    if n_markers is not None or run.marker_labels:
        text = f"{int(n_markers):,} on the face" if n_markers is not None else f"{len(run.marker_labels):,}"
        left_out = _texts(rep.get("markers_left_out"))
        if left_out:
            text += f"; {len(left_out)} left out of the solve ({_listed(left_out, 6)})"
        rows.append(("Markers", text))
    if run.rate is not None:
        text = f"{_quantity(run.rate, 'Hz')}"
        if n_frames is not None:
            text += f", {_duration(n_frames / run.rate)} of the take"
        rows.append(("Rate", text))
    if isinstance(perf.get("units"), str):
        rows.append(("Units", f"{perf['units']} (the unit of the written files)"))
    n_bases = _float(rep.get("n_bases"))
    planned = [int(f) for f in perf.get("planned_frames") or [] if _is_number(f)]
    if n_bases is not None or planned:
        count = int(n_bases) if n_bases is not None else len(planned)
        rows.append(("Scanned expressions", f"{count} scans" + (f", of take frames {_listed([str(f) for f in planned])}"
                                                                 if planned else "")))
    if isinstance(perf.get("frame"), str):
        rows.append(("Output frame", perf["frame"]))
    head = _head_motion_phrase(run)
    if head:
        rows.append(("Head motion", head))
    if isinstance(rep.get("rest_pose"), Mapping):
        rows.append(("Rest pose", _rest_pose_phrase(rep["rest_pose"], rest_frame)))
    edit = perf.get("edit")
    if isinstance(edit, Mapping) and isinstance(edit.get("kind"), str):
        rows.append(("Edit", edit["kind"]))
    total = _float(_get(rep, "timings", "total_s"))
    if total is None:
        total = _float(_get(perf, "timings", "total_s"))
    if total is not None:
        fps = _float(_get(rep, "timings", "frames_per_second")) or _float(_get(perf, "timings", "frames_per_second"))
        rows.append(("Time taken", _duration(total) + (f" ({_number(fps)} frames per second deforming and writing)"
                                                      if fps else "")))
    if "warnings" in rep or isinstance(_get(rep, "head_motion", "warnings"), list):
        n = len(run.warnings)
        rows.append(("Warnings", "none" if n == 0 else f"{n}, explained below"))
    rows.append(("Result folder", str(run.shown)))
    return "<h2 id=\"summary\">Summary</h2>" + _table(rows, css="summary")


# --------------------------------------------------------------------------------------------------- quality

def _at_frame(run: _Run, per_frame: np.ndarray | None) -> str:
    """' (frame k)' for the frame where a per-frame figure is largest."""
    if per_frame is None or per_frame.ndim != 1 or not np.isfinite(per_frame).any():
        return ""
    return f" (frame {run.first_frame + int(np.nanargmax(per_frame))})"


def _per_frame_and_largest(run: _Run, key: str, series_key: str) -> tuple[Any, np.ndarray | None, float | None]:
    """A report group (marked rendered), its per-frame series and its largest value (its ``max``, else the series')."""
    group = run.take(key)
    per = _series(_get(group, series_key))
    largest = _float(_get(group, "max"))
    if largest is None and per is not None:
        largest = float(np.nanmax(per))
    return group, per, largest


def _median(per_frame: np.ndarray) -> float:
    return float(np.nanmedian(per_frame))


def _animate_residual(run: _Run, plot: _Plotter) -> _Block | None:
    _, per, largest = _per_frame_and_largest(run, "marker_residual_mm", "per_frame_max")
    if largest is None:
        return None
    return _Block(
        "Marker residual", f"largest {_quantity(largest, 'mm')}{_at_frame(run, per)}",
        "How far each marker is from the point the deformed scan gives it (its place on the scan, lifted by the "
        "marker offset): the shell is built to pass through the markers.",
        "Good: a few hundredths of a millimetre. Tenths or more mean the marker-offset iterations did not settle.",
        plot({"largest over the markers": per}, ylabel="max marker residual (mm)",
             caption="The largest marker residual in each frame"), look=largest > 0.1)


def _blend_residual(run: _Run, plot: _Plotter) -> _Block | None:
    residual, per, largest = _per_frame_and_largest(run, "marker_residual_mm", "per_frame")
    if largest is None:
        return None
    mean = _float(_get(residual, "mean"))
    value = (f"mean {_quantity(mean, 'mm')} RMS, " if mean is not None else "") + \
        f"worst frame {_quantity(largest, 'mm')}{_at_frame(run, per)}"
    return _Block(
        "Marker residual", value,
        "RMS distance in each frame between the markers and the blend of the scanned expressions, after a small "
        "rigid correction of the frame's head pose.",
        "Good: near the markers' noise, a few tenths of a millimetre. Peaks are expressions that no scan holds: "
        "scanning a frame there lowers them.",
        plot({"RMS over the markers": per}, ylabel="marker RMS (mm)",
             caption="Marker residual of the blend in each frame"), look=largest > 1.0)


def _muscle_residual(run: _Run, plot: _Plotter) -> _Block | None:
    residual, per_max, largest = _per_frame_and_largest(run, "marker_residual_mm", "per_frame_max")
    per_marker, per_rms = _series(_get(residual, "per_frame")), _series(_get(residual, "per_frame_rms"))
    rms = _float(_get(residual, "rms"))
    if rms is None and largest is None:
        return None
    parts = []
    if rms is not None:
        parts.append(f"RMS {_quantity(rms, 'mm')} over the markers and frames")
    if largest is not None:
        parts.append(f"worst marker {_quantity(largest, 'mm')}{_at_frame(run, per_max)}")
    series = ({"markers": per_marker} if per_marker is not None and per_marker.ndim == 2
              else {"RMS over the markers": per_rms, "worst marker": per_max})
    return _Block(
        "Marker residual", ", ".join(parts),
        "How far the simulated skin misses the markers. The model makes only the faces its muscles and jaw can "
        "make, so this is larger than facecap animate's, which passes through the markers.",
        "Good: about 1–2 mm RMS. Several millimetres on most frames mean the model's face and the take's markers "
        "differ (another person's take, a generic map).",
        plot(series, ylabel="marker residual (mm)", caption="Marker residual of the simulated skin in each frame"),
        look=rms is not None and rms > 2.0)


def _leave_one_out(run: _Run, plot: _Plotter) -> _Block | None:
    loo = run.take("warp_leave_one_out_mm", "warp_outliers")
    if not isinstance(loo, Mapping):
        return None
    values = {str(k): float(v) for k, v in loo.items() if _float(v) is not None}
    if not values:
        return None
    flagged = _texts(run.report.get("warp_outliers"))
    worst = sorted(values.items(), key=lambda kv: -kv[1])
    median = float(np.median(list(values.values())))
    value = (f"median {_quantity(median, 'mm')}, largest "
             f"{_quantity(worst[0][1], 'mm')} ({worst[0][0]}); "
             + (f"flagged: {_listed(flagged)}" if flagged else "no marker flagged"))
    extra = ("<p class=\"about\">Largest: " + _e(", ".join(f"{k} {_quantity(v, 'mm')}" for k, v in worst[:5]))
             + " (every marker in the details).</p>")
    return _Block(
        "Leave-one-out warp residual", value,
        "Each marker in turn is left out of the warp that carries the take's rest frame onto the scan, and the "
        "place the other markers predict for it is compared with its place in the map: how well the map agrees "
        "with the take.",
        "Good: under about 1 mm on most markers for a map made for this scan and take (a generic map on another "
        "person's face gives several millimetres). Flagged markers stand far above the others and over 2 mm: "
        "likely on the wrong vertex or mislabelled.", look=bool(flagged) or median > 1.0, extra=extra)


def _rest_pose(run: _Run, plot: _Plotter) -> _Block | None:
    rest = run.take("rest_pose")
    if not isinstance(rest, Mapping):
        return None
    noise, mismatch = _float(rest.get("noise_mm")), _float(rest.get("mismatch_rms_mm"))
    rest_noise = _float(rest.get("rest_noise_mm"))
    parts = [_rest_pose_phrase(rest, run.report.get("rest_frame", run.performance.get("rest_frame")))]
    if mismatch is not None:
        # the noise the mismatch is weighed against is the rest markers' (averaged over the rest window) in 3-D,
        # as the sentence above states it; a single frame's per coordinate is another, larger, figure
        against = []
        if rest_noise is not None:
            against.append(f"the rest frame's noise of {_quantity(np.sqrt(3.0) * rest_noise, 'mm')} (3-D)")
        if noise is not None:
            against.append(f"a single frame's {_quantity(noise, 'mm')} a coordinate")
        parts.append(f"mismatch {_quantity(mismatch, 'mm')} RMS after the rigid fit"
                     + (f", against {' and '.join(against)}" if against else ""))
    split = [f"{name} {_quantity(v, 'mm')} RMS" for name, v in
             (("shared by neighbours", _float(rest.get("expression_rms_mm"))),
              ("each marker's own", _float(rest.get("placement_rms_mm"))))
             if v is not None]
    if split:
        parts.append("of which " + " and ".join(split))
    per_marker = {str(k): float(v) for k, v in (rest.get("per_marker_mm") or {}).items()
                  if _float(v) is not None} if isinstance(rest.get("per_marker_mm"), Mapping) else {}
    extra = ""
    if per_marker:
        worst = sorted(per_marker.items(), key=lambda kv: -kv[1])[:5]
        extra = ("<p class=\"about\">Farthest: " + _e(", ".join(f"{k} {_quantity(v, 'mm')}" for k, v in worst))
                 + " (every marker in the details).</p>")
    return _Block(
        "Rest pose against the scan", "; ".join(parts),
        "The take's rest frame fitted to the markers' places on the scan by a robust rigid fit (markers that moved "
        "weigh less); what remains is split into the part neighbouring markers share (an expression moves the "
        "skin together) and each marker's own part (a map picked by hand is off marker by marker). Mode 'scan' "
        "warps the whole difference away; mode 'expression' keeps it as motion.",
        "Good: a mismatch near the noise: the rest frame shows the scan's expression. Well above it, the resting "
        "face or the markers' places differ from the scan's: check that the mode chosen fits the take.",
        look=mismatch is not None and noise is not None and mismatch > 3 * noise, extra=extra)


def _head_motion(run: _Run, plot: _Plotter) -> _Block | None:
    head = run.take("head_motion")
    if not isinstance(head, Mapping):
        return None
    phrase = _head_motion_phrase(run) or ""
    stable = _texts(head.get("stable_markers"))
    mode = head.get("mode") if isinstance(head.get("mode"), str) else None
    about = ("The head's rigid motion in the take, taken out of the face's animation so that the face moves "
             "only with its expressions; it is written to head_motion.npy, which puts the face back where the "
             "capture saw it.")
    if stable:
        about += f" Rigid set: {_listed(stable)}."
    if mode:
        about += f" Mode: {mode}."
    moving = head.get("moving_stable_markers") if isinstance(head.get("moving_stable_markers"), Mapping) else {}
    if moving:
        about += (" Markers of the rigid set that may move with the face: "
                  + "; ".join(f"{k} ({v})" for k, v in moving.items()) + ".")
    return _Block(
        "Head motion", phrase[:1].upper() + phrase[1:], about,
        "Any amount is fine as long as the markers it comes from are rigid on the skull (see the stabilisation "
        "residual); a rigid set on the jaw or lips mixes expression into the head motion.",
        look=bool(_texts(head.get("warnings"))) or bool(head.get("moving_stable_markers")))


def _spread_block(run: _Run, plot: _Plotter, per: np.ndarray | None, *, title: str, about: str, good: str,
                  legend: str, ylabel: str, caption: str) -> _Block | None:
    """A per-frame figure in mm: its median and largest (with the frame), plotted; a look above 1 mm median."""
    if per is None or per.ndim != 1:
        return None
    median = _median(per)
    return _Block(title, f"median {_quantity(median, 'mm')}, largest {_quantity(float(np.nanmax(per)), 'mm')}"
                  f"{_at_frame(run, per)}", about, good, plot({legend: per}, ylabel=ylabel, caption=caption),
                  look=median > 1.0)


def _stabilisation(run: _Run, plot: _Plotter) -> _Block | None:
    return _spread_block(
        run, plot, _series(run.take("stabilization_residual_mm")), title="Stabilisation residual",
        about="RMS distance in each frame of the head's rigid markers from their best rigid fit: how rigid that "
              "set really is.",
        good="Good: about the markers' noise, under 0.5 mm. Above 1 mm the 'rigid' markers slide with the skin (or "
             "one sits on the jaw), and expression leaks into the head motion.",
        legend="RMS over the rigid markers", ylabel="rigid-set RMS (mm)",
        caption="How far the head's rigid markers are from a rigid motion in each frame")


def _conditioning(run: _Run, plot: _Plotter) -> _Block | None:
    return _spread_block(
        run, plot, _series(_get(run.take("conditioning_mm"), "per_frame_rms_change")), title="Change by conditioning",
        about="RMS distance in each frame between the markers as captured and as used, after the noise filter and "
              "the gap filling (the head motion taken out of both).",
        good="Good: about the capture's noise, a few tenths of a millimetre. Much more means the filter smooths real "
             "motion, or long gaps were filled.",
        legend="RMS over the markers", ylabel="RMS change (mm)",
        caption="How much the filter and gap filling moved the markers in each frame")


def _temporal_sigma(run: _Run, plot: _Plotter) -> _Block | None:
    sigma_report = run.take("temporal_sigma", "temporal_sigma_s")
    sigma = _float(_get(sigma_report, "sigma_s"))
    if sigma is None:
        sigma = _float(run.report.get("temporal_sigma_s"))
    if sigma is None:
        return None
    chosen = _get(sigma_report, "chosen_by")
    value = _quantity(sigma, "s")
    if run.rate is not None:
        value += f" ({_number(sigma * run.rate)} frames at {_quantity(run.rate, 'Hz')})"
    if isinstance(chosen, str):
        value += f", {chosen}" if chosen == "given" else f", chosen by {chosen}"
    candidates = _series(_get(sigma_report, "candidates_s"))
    good = ""
    look = False
    if candidates is not None and candidates.ndim == 1 and np.isfinite(candidates).all():
        low, high = float(candidates.min()), float(candidates.max())
        if math.isclose(sigma, low):
            good = ("At the smallest width tried: the take already looks smooth (filtered in the capture software, "
                    "or clean), and the filter changes almost nothing.")
        elif math.isclose(sigma, high):
            good = ("At the largest width tried: the take is noisy; a wider filter might predict better but would "
                    "also smooth fast motion. Check the take's noise in the review.")
            look = True
        else:
            good = f"Good: inside the range tried ({_number(low)}–{_quantity(high, 's')}), the usual case."
    return _Block(
        "Noise filter width", value,
        "The width in time (Gaussian sigma) of the filter that smooths the markers' noise: each frame is "
        "predicted from its neighbours, and the width that predicts best among those tried is used.",
        good, look=look)


def _offset_correction(run: _Run, plot: _Plotter) -> _Block | None:
    correction, per, largest = _per_frame_and_largest(run, "marker_offset_correction_mm", "per_frame_max")
    if largest is None:
        return None
    mean = _float(_get(correction, "mean"))
    offset = _float(_get(run.performance, "parameters", "marker_offset_mm"))
    return _Block(
        "Marker offset correction",
        (f"mean {_quantity(mean, 'mm')}, " if mean is not None else "") + f"largest {_quantity(largest, 'mm')}"
        + _at_frame(run, per),
        "Markers sit above the skin (the marker offset" + (f", {_quantity(offset, 'mm')} here" if offset else "")
        + "); where the face bends, the skin under a marker moves differently from the marker. This is how far "
        "the skin's motion was corrected for it.",
        "Good: tenths of a millimetre. Several millimetres mean the offset does not match the markers' size.",
        plot({"largest over the markers": per}, ylabel="max correction (mm)",
             caption="The largest marker offset correction in each frame"), look=largest > 3.0)


def _filled(run: _Run, plot: _Plotter) -> _Block | None:
    filled = _float(run.take("filled_samples"))
    if filled is None:
        return None
    T, M = run.number("n_frames"), run.number("n_markers")
    total = int(T * M) if T and M else None
    share = 100.0 * filled / total if total else None
    value = f"{int(filled):,}" + (f" of {total:,} marker samples ({_number(share)}%)" if share is not None
                                  else " marker samples")
    return _Block(
        "Filled gaps", value,
        "Marker samples missing from the take (occlusions) and filled from the neighbouring frames and markers.",
        "Good: a few percent. A long gap on one marker shows in the review as a track that moves too smoothly.",
        look=share is not None and share > 10.0)


def _muscle_flags(run: _Run, plot: _Plotter) -> _Block | None:
    flags = run.take("flags", "frames_flagged")
    if not isinstance(flags, Mapping):
        return None
    counts: dict[str, int] = {}
    for names in flags.values():
        for name in _texts(names):
            counts[name] = counts.get(name, 0) + 1
    n = len([f for f in flags.values() if f])
    T = run.number("n_frames")
    value = f"{n} of {int(T)} frames flagged" if T is not None else f"{n} frames flagged"
    if counts:
        value += ": " + ", ".join(f"{c} {name.replace('_', ' ')}" for name, c in counts.items())
    items = "".join(f"<li><strong>{_e(name.replace('_', ' '))}</strong>: "
                    f"{_e(_MUSCLE_FLAGS.get(name, 'see docs/muscles.md'))}</li>" for name in counts)
    return _Block(
        "Flagged frames", value,
        "A frame is flagged when something in its solve is worth a look." + (" The flags here mean:" if items else ""),
        "Good: no flags. 'large residual' on most frames usually means the take's markers and the model's face "
        "differ (another person's take, a generic map): compare with the marker residual above.",
        look=n > 0, extra=f"<ul class=\"notes\">{items}</ul>" if items else "")


def _muscle_effort(run: _Run, plot: _Plotter) -> _Block | None:
    iterations = _series(run.take("newton_iterations"))
    inverted = _series(run.take("inverted_tets"))
    violation = _float(run.take("constraint_violation_max"))
    if iterations is None and inverted is None and violation is None:
        return None
    parts = []
    if iterations is not None and iterations.ndim == 1:
        parts.append(f"Newton iterations per frame: median {_number(_median(iterations))}, "
                     f"most {_number(float(np.nanmax(iterations)))}")
    worst_inverted = float(np.nanmax(inverted)) if inverted is not None else None
    if worst_inverted is not None:
        parts.append(f"inverted tetrahedra: {'none' if worst_inverted == 0 else _number(worst_inverted) + ' at most'}")
    if violation is not None:
        parts.append(f"largest constraint violation {_number(violation)}")
    return _Block(
        "Simulation", "; ".join(parts),
        "How hard the flesh simulation worked per frame, and whether its solved state is physical.",
        "Good: a few iterations per frame, no inverted tetrahedra, a constraint violation under 1e-4.",
        look=bool(worst_inverted) or (violation is not None and violation > 1e-4))


def _edit_convergence(run: _Run, plot: _Plotter) -> _Block | None:
    converged = run.take("converged", "not_converged_frames", "newton_iterations", "residual_mn",
                         "seconds_per_frame", "frames")
    if not isinstance(converged, list) or not converged:
        return None
    bad = _texts(run.report.get("not_converged_frames"))
    n = len(converged)
    value = f"{n - len(bad)} of {n} frames converged" + (f"; not converged: frames {_listed(bad)}" if bad else "")
    residual = _series(run.report.get("residual_mn"))
    return _Block(
        "Convergence", value,
        "Each edited frame is a new equilibrium of the simulated flesh; converged means its forces balance within "
        "the solver's tolerance.", "Good: every frame converged.",
        plot({"force residual": residual}, ylabel="force residual (mN)",
             caption="The simulation's force residual in each edited frame"), look=bool(bad))


def _skin_change(run: _Run, plot: _Plotter) -> _Block | None:
    change, most, largest = _per_frame_and_largest(run, "skin_change_mm", "per_frame_max")
    mean = _series(_get(change, "per_frame_mean"))
    if largest is None:
        return None
    return _Block(
        "Skin change", f"largest {_quantity(largest, 'mm')}{_at_frame(run, most)}",
        "How far the edit moved the skin from the result it started from, in each frame.",
        "This is the edit itself: check in the review that it is where it was wanted and small elsewhere.",
        plot({"mean over the skin": mean, "largest": most}, ylabel="skin change (mm)",
             caption="How far the edit moved the skin in each frame"))


def _sphere(run: _Run, plot: _Plotter) -> _Block | None:
    sphere = run.take("sphere")
    depth = _float(_get(sphere, "max_scan_penetration_mm"))
    if depth is None:
        return None
    tolerance = _float(_get(run.performance, "edit", "penetration_tolerance_mm"))
    return _Block(
        "Contact", f"deepest penetration of the skin {_quantity(depth, 'mm')}"
        + (f" (tolerance {_quantity(tolerance, 'mm')})" if tolerance is not None else ""),
        "How far the pressing sphere still sinks into the skin where it touches it.",
        "Good: under the penetration tolerance.", look=tolerance is not None and depth > tolerance)


def _head_pose_correction(run: _Run, plot: _Plotter) -> _Block | None:
    correction = run.take("head_pose_correction")
    rotation = _float(_get(correction, "rotation_deg", "max"))
    translation = _float(_get(correction, "translation_mm", "max"))
    if rotation is None or translation is None:
        return None
    return _Block(
        "Head pose correction", f"up to {_quantity(rotation, '°')} and {_quantity(translation, 'mm')}",
        "The small rigid correction of each frame's head pose found together with the blend weights, on top of the "
        "take's stabilisation.",
        "Good: a fraction of a degree and of a millimetre. More means the stabilisation was off in those frames.",
        look=rotation > 1.0 or translation > 2.0)


def _wrinkles(run: _Run, plot: _Plotter) -> _Block | None:
    frames = run.wrinkles.get("frames")
    if not isinstance(frames, list) or not frames:
        return None
    identities, per_frame, depths, widths, drawn = set(), [], [], [], 0
    for frame in frames:
        wrinkles = [w for w in (frame.get("wrinkles") if isinstance(frame, Mapping) else None) or []
                    if isinstance(w, Mapping)]
        per_frame.append(len(wrinkles))
        for w in wrinkles:
            identities.add(str(w.get("wrinkle")))
            drawn += w.get("drawn") is True
            for key, into in (("depth_mm", depths), ("width_mm", widths)):
                values = _series(w.get(key))
                if values is not None:
                    into.append(values[np.isfinite(values)])
    value = (f"{len(identities)} wrinkles over {len(frames)} video frames "
             f"({_number(float(np.mean(per_frame)))} per frame)")
    deepest = float(np.max(np.abs(np.concatenate(depths)))) if depths else None
    if deepest is not None:
        value += f", deepest {_quantity(deepest, 'mm')}"
    if widths:
        value += f", median width {_quantity(float(np.median(np.concatenate(widths))), 'mm')}"
    if drawn:
        value += f"; {drawn} drawn by hand"
    return _Block(
        "Wrinkles", value,
        "Wrinkles found in the footage by their paint, placed on the face from the cameras and carved into the "
        "large-scale face as cross-sections of measured depth and width.",
        "Good: every painted wrinkle found in every frame (the warnings name those lost), and depths plausible for "
        "skin: tenths of a millimetre to about 2 mm.", look=deepest is not None and deepest > 3.0)


def _scan_bases(run: _Run, plot: _Plotter) -> _Block | None:
    bases = [b for b in (run.take("scan_bases") or []) if isinstance(b, Mapping)]
    if not bases:
        return None

    def mean(entry: Mapping[str, Any], key: str) -> float:
        """The figure (or its ``mean``), NaN where missing."""
        value = entry.get(key)
        number = _float(value.get("mean")) if isinstance(value, Mapping) else _float(value)
        return np.nan if number is None else number

    def shown(x: float) -> str:
        return _number(x) if np.isfinite(x) else "–"

    marker = np.array([mean(b, "marker_residual_mm") for b in bases])
    slide = np.array([mean(b, "tangential_motion_mm") for b in bases])
    mismatch = [[_float(m) for m in b.get("colour_mismatch_by_round") or []] for b in bases]
    coloured = any(m for m in mismatch)
    typical = float(np.nanmedian(marker)) if np.isfinite(marker).any() else np.nan
    # a basis whose markers disagree with it far more than the others' do, or whose texture still looks unrelated
    odd = [i for i, b in enumerate(bases) if (np.isfinite(marker[i]) and marker[i] > max(3.0 * typical, 0.5))
           or (mismatch[i] and (mismatch[i][-1] or 0.0) > 0.2)]
    rows = []
    for i, b in enumerate(bases):
        row = [str(b.get("basis", i)), str(b.get("frame", "")), Path(str(b.get("scan") or "")).name,
               shown(mean(b, "registration_mm")), shown(marker[i]), shown(slide[i])]
        if coloured:
            row += [" -> ".join(_number(m) for m in mismatch[i] if m is not None) or "–",
                    shown(mean(b, "colour_alignment_moved_mm"))]
        rows.append(row + ["look at this" if i in odd else ""])
    head = ["basis", "frame", "scan", "to its scan (mm)", "markers before the fit (mm)", "slid along the skin (mm)"]
    if coloured:
        head += ["texture mismatch by round", "moved by colour (mm)"]
    table = _grid([*head, "note"], rows, [True, True, False, True, True, True, *([False, True] if coloured else []),
                                          False], css="bases")
    colour_note = (" Texture mismatch: how far the band-passed textures of the scan and the template differ where "
                   "both are seen, at the start of each colour-alignment round (measured: about 0.08 when the "
                   "textures line up, 0.10 for a slide of 1.5 mm, 0.37 against an unrelated texture)."
                   if coloured else "")
    return _Block(
        "Scan bases", f"{len(bases)} bases" + (f"; markers disagree with their basis by {_quantity(typical, 'mm')} "
                                               "(median of the bases' means) before the section-7 fit"
                                               if np.isfinite(typical) else ""),
        "Each registered scan, read without truth: its mean distance to its scan, how far its frame's markers were "
        "from it before the fit pins it to them (a pose or correspondence error shows here first), and how far "
        "the template slid along itself to reach the scan (expressions slide skin a few millimetres at most)."
        + colour_note,
        "Good: a few hundredths of a millimetre to the scan, marker disagreements of a few tenths, all bases "
        "alike. A basis far above the others is marked: check its scan (the planned expression? the frame?).",
        look=bool(odd), extra=f"<details{' open' if odd else ''}><summary>Per basis</summary>{table}</details>")


_ANIMATE_FIGURES = (_animate_residual, _leave_one_out, _rest_pose, _head_motion, _stabilisation, _conditioning,
                    _temporal_sigma, _offset_correction, _filled)

_FIGURES: dict[str, tuple[Callable[[_Run, _Plotter], _Block | None], ...]] = {
    "bickel2007-large-scale": _ANIMATE_FIGURES,
    "huang2011-blendshapes": (_blend_residual, _scan_bases, _head_pose_correction, _head_motion, _rest_pose),
    "sifakis2005-muscle-activations": (_muscle_residual, _muscle_flags, _muscle_effort, _rest_pose, _head_motion,
                                       _stabilisation, _conditioning, _temporal_sigma, _filled),
    "sifakis2005-muscle-edit": (_edit_convergence, _skin_change, _sphere),
    "bickel2007-medium-scale": (_wrinkles,),
}
"""The quality figures of each method, in reading order; animate's for a report of another method."""


def _quality(run: _Run, plot: _Plotter) -> str:
    figures = _FIGURES.get(run.method or "", _ANIMATE_FIGURES)
    blocks = [b for b in (figure(run, plot) for figure in figures) if b is not None]
    if not blocks:
        return ""
    return "<h2 id=\"quality\">Quality</h2>" + "".join(b.html() for b in blocks)


# --------------------------------------------------------------------------------------------------- warnings

def _warnings(run: _Run) -> str:
    parts = []
    messages = run.warnings
    if messages:
        parts.append("<h2 id=\"warnings\">Warnings</h2>")
        for message in messages:
            advice = explain_warning(message)
            parts.append(f"<div class=\"warning\"><p class=\"message\">{_e(message)}</p>"
                         f"<p><strong>What it means:</strong> {_e(advice.meaning)}</p>"
                         f"<p><strong>What to do:</strong> {_e(advice.action)}</p></div>")
    notes = _texts(run.take("notes"))
    if notes:
        parts.append("<h2 id=\"notes\">Notes</h2><ul class=\"notes\">"
                     + "".join(f"<li>{_e(n)}</li>" for n in notes) + "</ul>")
    return "".join(parts)


# --------------------------------------------------------------------------------------------------- details

def _timings(run: _Run) -> list[tuple[str, str]]:
    timings: dict[str, Any] = {}
    for source in (run.performance.get("timings"), run.report.get("timings")):
        if isinstance(source, Mapping):
            timings.update(source)
    run.used.add("timings")
    for key in ("weights_s",):  # blend's one timing
        if _float(run.report.get(key)) is not None:
            timings.setdefault(key, run.report[key])
            run.used.add(key)
    rows = []
    for key, value in sorted(timings.items(), key=lambda kv: kv[0] == "total_s"):
        seconds = _float(value)
        if seconds is None:
            continue
        rows.append((_label(key), _duration(seconds) if key.endswith("_s") else _number(seconds)))
    return rows


def _files(run: _Run) -> str:
    files = {name: size for name, size in run.files.items() if name != "report.html"}
    if not files:
        return ""
    rows = [[name, _size(size)] for name, size in sorted(files.items())]
    rows.append(["all files", _size(sum(files.values()))])
    return "<h3>Files</h3>" + _grid(["file", "size"], rows, [False, True], css="files")


def _per_marker(run: _Run) -> str:
    columns: list[tuple[str, dict[str, float]]] = []
    loo = run.report.get("warp_leave_one_out_mm")
    if isinstance(loo, Mapping):
        columns.append(("leave-one-out warp residual (mm)",
                        {str(k): float(v) for k, v in loo.items() if _float(v) is not None}))
    rest = _get(run.report, "rest_pose", "per_marker_mm")
    if isinstance(rest, Mapping):
        columns.append(("rest pose: distance from the scan after the rigid fit (mm)",
                        {str(k): float(v) for k, v in rest.items() if _float(v) is not None}))
    labels = _texts(_get(run.report, "marker_residual_mm", "labels"))
    matrix = _series(_get(run.report, "marker_residual_mm", "per_frame"))
    if labels and matrix is not None and matrix.ndim == 2 and matrix.shape[1] == len(labels):
        seen = np.isfinite(matrix).any(axis=0)
        with np.errstate(invalid="ignore"):
            rms = np.sqrt(np.nanmean(np.where(seen, matrix, 0.0) ** 2, axis=0))
        columns.append(("residual RMS over the frames (mm)", {k: float(v) for k, v, s in zip(labels, rms, seen) if s}))
        columns.append(("largest residual (mm)", {k: float(np.nanmax(matrix[:, j])) for j, k in enumerate(labels)
                                                  if seen[j]}))
    columns = [c for c in columns if c[1]]
    if not columns:
        return ""
    notes: dict[str, list[str]] = {}
    for label in _texts(run.report.get("warp_outliers")):
        notes.setdefault(label, []).append("flagged")
    for label in _texts(_get(run.report, "head_motion", "stable_markers")) or _texts(
            _get(run.performance, "parameters", "stable_markers")):
        notes.setdefault(label, []).append("rigid set (head)")
    for label in _texts(run.report.get("markers_left_out")):
        notes.setdefault(label, []).append("left out")
    order = list(dict.fromkeys([k for _, values in columns for k in values] + list(notes)))
    first = columns[0][1]
    order.sort(key=lambda k: -first.get(k, -np.inf))
    rows = [[k, *[_number(values[k]) if k in values else "–" for _, values in columns], ", ".join(notes.get(k, []))]
            for k in order]
    table = _grid(["marker", *[title for title, _ in columns], "note"], rows,
                  [False, *[True] * len(columns), False], css="markers")
    return (f"<details><summary>Per marker ({len(order)} markers, the largest {columns[0][0].split(' (')[0]} "
            f"first)</summary>{table}</details>")


def _mesh_check(run: _Run) -> str:
    check = run.take("mesh_check")
    pieces = run.take("pieces")
    if not isinstance(check, Mapping):
        return ""
    rows = []
    n_v, n_f = _float(check.get("n_vertices")), _float(check.get("n_faces"))
    if n_v is not None and n_f is not None:
        rows.append(("Vertices and triangles", f"{int(n_v):,} vertices, {int(n_f):,} triangles"))
    box = _series(check.get("bounding_box_mm"))
    if box is not None and box.shape == (2, 3):
        extent = box[1] - box[0]
        rows.append(("Size", " × ".join(_number(float(x)) for x in extent) + " mm"))
    edge = _float(check.get("mean_edge_length_mm"))
    if edge is not None:
        rows.append(("Mean edge length", _quantity(edge, "mm")))
    n_pieces = _float(check.get("n_pieces"))
    if n_pieces is not None:
        text = f"{int(n_pieces)}"
        unmarked = _get(pieces, "unmarked_pieces")
        if isinstance(unmarked, list):
            policy = _get(pieces, "unmarked_policy")
            text += (", every piece carries markers" if not unmarked else
                     f", {len(unmarked)} without markers" + (f" ({policy})" if isinstance(policy, str) else ""))
        rows.append(("Pieces", text))
    loops, edges = _float(check.get("n_boundary_loops")), _float(check.get("n_boundary_edges"))
    if loops is not None:
        rows.append(("Open boundaries", f"{int(loops)} loop{'' if int(loops) == 1 else 's'}"
                     + (f" ({int(edges):,} edges)" if edges is not None else "")
                     + ": the scan's edge and its openings (eyes, mouth)"))
    defects = {"n_nonfinite_vertices": "non-finite vertices", "n_out_of_range_faces": "faces with indices out of range",
               "n_degenerate_faces": "degenerate triangles", "n_unreferenced_vertices": "unreferenced vertices",
               "n_duplicate_vertices": "duplicate vertices", "n_non_manifold_edges": "non-manifold edges"}
    found = [f"{int(check[k]):,} {name}" for k, name in defects.items() if (_float(check.get(k)) or 0) > 0]
    welded = _float(_get(pieces, "welded_vertices"))
    if welded:
        found.append(f"{int(welded):,} vertices welded")
    rows.append(("Defects", "; ".join(found) if found else "none found (" + ", ".join(defects.values()) + ")"))
    problems = _texts(check.get("problems"))
    if problems:
        rows.append(("Problems", "; ".join(problems)))
    return "<h3>Mesh check</h3>" + _table(rows)


_NOT_SHOWN = {"format", "version", "frames_in", "markers", "muscles", "files", "labels"}
"""``performance.json`` keys a reader does not need (the file's format; lists shown elsewhere)."""

_PERFORMANCE_SHOWN = {"rate", "units", "n_frames", "n_vertices", "source_files", "source_units", "method",
                      "rest_frame", "stabilized", "parameters", "first_frame", "map", "timings", "exports",
                      "exports_report", "frame", "planned_frames", "large_scale", "footage", "cameras",
                      "video_rate_hz", "edit", "frames", "depth_scale", "anchored", "first_mocap_frame",
                      "retarget"}
"""``performance.json`` keys the summary and the details show by name."""

_REPORT_SHOWN = {"n_frames", "n_vertices", "n_markers", "rest_frame", "first_frame", "n_tets", "n_muscles",
                 "n_bases", "markers_left_out", "warnings", "edit"}


def _details(run: _Run) -> str:
    perf = run.performance
    parts = []
    timings = _timings(run)
    if timings:
        parts.append("<h3>Timings</h3>" + _table(timings))
    parts.append(_files(run))
    parameters = perf.get("parameters")
    rows = _rows(parameters) if isinstance(parameters, Mapping) else []
    for key in ("edit", ):
        if isinstance(perf.get(key), Mapping):
            rows += _rows(perf[key], f"{_label(key)}: ")
    for key in ("depth_scale", "anchored", "first_mocap_frame"):
        if key in perf and not isinstance(perf[key], (Mapping, list)):
            rows.append((_label(key), _value(key, perf[key])))
    if rows:
        parts.append("<h3>Parameters</h3>" + _table(rows))
    sources = perf.get("source_files") if isinstance(perf.get("source_files"), Mapping) else {}
    inputs = [(_INPUTS.get(k, _label(k)), ", ".join(str(p) for p in (v if isinstance(v, list) else [v])))
              for k, v in {**{k: perf[k] for k in ("map", "large_scale", "footage") if perf.get(k)}, **sources}.items()
              if v not in (None, "", [])]
    if inputs:
        parts.append("<h3>Inputs</h3><table><tbody>" + "".join(
            f"<tr><th>{_e(k)}</th><td class=\"path\">{_e(v)}</td></tr>" for k, v in inputs) + "</tbody></table>")
    exports = perf.get("exports_report")
    if isinstance(exports, Mapping) and exports:
        trimmed = {fmt: {k: v for k, v in data.items() if k not in ("files", "bytes")} if isinstance(data, Mapping)
                   else data for fmt, data in exports.items()}
        parts.append("<h3>Exports</h3>" + _table(_rows(trimmed)))
    parts.append(_per_marker(run))
    parts.append(_mesh_check(run))
    other = {k: v for k, v in run.report.items()
             if k not in run.used and k not in _REPORT_SHOWN and k not in _NOT_SHOWN and v is not None}
    other.update({k: v for k, v in perf.items()
                  if k not in _PERFORMANCE_SHOWN and k not in _NOT_SHOWN and k not in other and v is not None})
    if other:
        parts.append("<h3>Other figures</h3>" + _table(_rows(other)))
    body = "".join(p for p in parts if p)
    return f"<h2 id=\"details\">Details</h2>{body}" if body else ""


# --------------------------------------------------------------------------------------------------- the page

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
    drawn_plots: dict[bytes, bytes] | None = None,
) -> Path:
    """Write the report of a run: summary, quality figures explained, warnings explained, details.

    Parameters
    ----------
    out_html : str or path-like
        HTML file to write (atomically: a temporary sibling renamed on success).
    result_dir : str or path-like
        The run's result folder; its ``performance.json`` (command, inputs, rate, units,
        parameters, timings), ``wrinkles.json`` and file sizes are read when present.
    report : mapping, str, path-like or None, optional
        The run's figures (the content of ``report.json``, or the path of a JSON file); default
        None reads ``result_dir/report.json``, else ``result_dir/blend_report.json``, when present.
    pictures : sequence of str or path-like, optional
        PNG pictures of the run, embedded in this order (base64), captioned.
    review_page : str, path-like or None, optional
        The run's review page (:func:`~facecap.report.write_review_page`), linked by its path
        relative to ``out_html``.
    title : str or None, optional
        Heading; default ``'<command>: <result folder name>'``.
    drawn_plots : dict, optional
        Plots drawn for this run, kept by what they show: a page written again with the same dict
        draws only what changed (a job writes its page beside its exports, whose results it also
        shows, then again after them). Default None: every plot drawn.

    Returns
    -------
    pathlib.Path
        ``out_html``.

    Raises
    ------
    InputError
        If ``result_dir`` is not a folder, a JSON file is unreadable or not an object, or a
        picture is missing or not a PNG. Missing or malformed figures are not errors: the
        parts that need them are left out.

    Notes
    -----
    The layout and what each part holds are described in this module's docstring. Figures
    are rendered by name (the quality figures of each command, with what they mean); any
    other figure of the report is listed under 'Other figures' with its key written as words
    and its unit, so nothing the run recorded is hidden and no raw key is shown.
    """
    result = Path(result_dir)
    if not result.is_dir():
        raise InputError("result folder not found", path=str(result))
    shown = final_path(result)  # where the folder will be: never a staging name
    out = Path(out_html)
    if report is None:
        report_data = _read_json(result / "report.json") or _read_json(result / "blend_report.json") or {}
    elif isinstance(report, (str, os.PathLike)):
        report_data = _read_json(Path(report))
        if report_data is None:
            raise InputError("report file not found", path=str(report))
    elif isinstance(report, Mapping):
        report_data = _plain(report)
    else:
        raise InputError(f"report: expected a mapping or the path of a JSON file, got {type(report).__name__}")
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
    run = _Run(shown=shown, performance=_read_json(result / "performance.json") or {}, report=report_data,
               wrinkles=_read_json(result / "wrinkles.json") or {}, files=file_sizes(result))

    command = run.command[0] if run.command else "facecap run"
    parts = [f"<h1>{_e(title or f'{command}: {shown.name}')}</h1>",
             f"<p class=\"meta\">written {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC by "
             f"facecap {_e(__version__)}</p>"]
    if review_page is not None:
        href = Path(os.path.relpath(Path(review_page).resolve(), out.resolve().parent)).as_posix()
        parts.append(f"<p class=\"review\"><a id=\"review-link\" class=\"review-link\" href=\"{_e(href)}\">"
                     "Open the review page (the animation in 3D)</a></p>")
    with tempfile.TemporaryDirectory(prefix="facecap-report-") as scratch:
        parts.append(_summary(run))
        parts.append(_quality(run, _Plotter(Path(scratch), run.first_frame, drawn_plots)))
    parts.append(_warnings(run))
    if images:
        parts.append("<h2 id=\"pictures\">Pictures</h2>")
        for name, png in images:
            caption = _PICTURES.get(name, name)
            parts.append(f"<figure><img alt=\"{_e(name)}\" src=\"{_data_uri(png)}\">"
                         f"<figcaption>{_e(caption)}</figcaption></figure>")
    parts.append(_details(run))
    page = ("<!doctype html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
            "<link rel=\"icon\" href=\"data:,\">\n"
            f"<title>{_e(title or f'{command}: {shown.name}')}</title>\n<style>{_STYLE}</style>\n</head>\n"
            "<body>\n" + "\n".join(p for p in parts if p) + "\n</body>\n</html>\n")
    with atomic_path(out) as tmp:
        tmp.write_text(page, encoding="utf-8")
    return out
