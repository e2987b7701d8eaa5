"""Wrinkle editing (Bickel et al. 2007, 6.2): deeper or shallower wrinkles, and wrinkles drawn by hand.

An edit file is JSON (frames are mocap frames of the take, inclusive ranges; an edit applies at the video
frames in its range and, as every wrinkle, blends linearly over the video interval after them)::

    {
      "depth": [
        {"scale": 0.5},                                             # every wrinkle, every frame
        {"scale": 2.0, "wrinkles": ["cam_left:2"], "frames": [40, 80]}
      ],
      "add": [
        {"camera": "cam_left", "frames": [40, 80], "depth_mm": 0.6, "width_mm": 2.0,
         "curve_px": [[612, 310], [660, 300], [705, 305]]},
        {"camera": "cam_right", "depth_mm": 0.8, "width_mm": 2.5,
         "svg_path": "M 700 640 C 720 700 740 740 780 760"}
      ]
    }

``wrinkles`` names identities as ``wrinkles.json`` writes them (``'<camera>:<id>'``); a merged wrinkle
is scaled when any camera's identity of it is named. Scales multiply. A drawn wrinkle is a valley line in
one camera's image (pixels, OpenCV convention: ``curve_px`` points, ``svg_path`` path data as an SVG editor
writes it, or ``svg_file`` whose first ``<path>`` is used) with a depth and width (its depth eases to 0
over the last 15 % of its length at each end), cast onto each frame's large scale like a tracked one.
"""

from __future__ import annotations

import json
import os
import warnings
import xml.etree.ElementTree as ElementTree
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FacecapWarning, InputError
from ..typing import FloatArray

__all__ = ["WrinkleEdits", "DrawnWrinkle", "DepthEdit", "read_wrinkle_edits", "svg_path_points"]

_END_EASE = 0.15


def svg_path_points(d: str, *, spacing_px: float = 4.0) -> FloatArray:
    """Points every ``spacing_px`` along SVG path data (lines, arcs, Bezier curves), (k, 2) px."""
    from svg.path import parse_path

    try:
        path = parse_path(d)
        length = float(path.length())
    except Exception as exc:  # svg.path raises several types on malformed data
        raise InputError(f"svg_path: not SVG path data ({exc})") from None
    if not np.isfinite(length) or length <= 0:
        raise InputError("svg_path: the path has no length")
    # dense in the path's parameter, then resampled uniformly in arc length (the parameter is not)
    z = np.array([path.point(float(x)) for x in np.linspace(0.0, 1.0, max(int(8 * length / spacing_px), 64) + 1)])
    dense = np.column_stack([z.real, z.imag])
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
    u = np.linspace(0.0, arc[-1], max(int(np.ceil(arc[-1] / spacing_px)) + 1, 2))
    return np.column_stack([np.interp(u, arc, dense[:, 0]), np.interp(u, arc, dense[:, 1])])


@dataclass(frozen=True)
class DepthEdit:
    """Scale the depth of ``wrinkles`` (None: all) over mocap frames ``first..last`` (None: all)."""

    scale: float
    wrinkles: tuple[str, ...] | None = None
    frames: tuple[float, float] | None = None

    def applies(self, wrinkle: str, mocap_frame: float) -> bool:
        if self.frames is not None and not self.frames[0] <= mocap_frame <= self.frames[1]:
            return False
        from .surface_wrinkles import names_wrinkle

        return self.wrinkles is None or names_wrinkle(wrinkle, self.wrinkles)


@dataclass(frozen=True)
class DrawnWrinkle:
    """A valley line drawn in one camera's image, with its depth and width (mm)."""

    camera: str
    curve_px: FloatArray
    depth_mm: float
    width_mm: float
    frames: tuple[float, float] | None = None
    name: str = "drawn"


@dataclass(frozen=True)
class WrinkleEdits:
    """Depth edits and drawn wrinkles (see the module docstring)."""

    depth: tuple[DepthEdit, ...] = ()
    add: tuple[DrawnWrinkle, ...] = field(default_factory=tuple)

    def describe(self) -> dict[str, Any]:
        """JSON-ready content (the frame runner records it with the run's parameters)."""
        return {"depth": [{"scale": e.scale, "wrinkles": e.wrinkles, "frames": e.frames} for e in self.depth],
                "add": [{"camera": d.camera, "curve_px": np.round(d.curve_px, 4).tolist(), "depth_mm": d.depth_mm,
                         "width_mm": d.width_mm, "frames": d.frames, "name": d.name} for d in self.add]}

    def scales(self, names: Sequence[str], mocap_frame: float) -> dict[str, float]:
        """The depth factor of each wrinkle at a frame."""
        out = {}
        for name in names:
            scale = 1.0
            for edit in self.depth:
                if edit.applies(name, mocap_frame):
                    scale *= edit.scale
            out[name] = scale
        return out

    def drawn_at(self, mocap_frame: float) -> list[DrawnWrinkle]:
        """The drawn wrinkles present at a frame."""
        return [d for d in self.add if d.frames is None or d.frames[0] <= mocap_frame <= d.frames[1]]

    def surface_wrinkles(self, mocap_frame: float, cameras: Sequence[Any], caster: Any, face_vertices: Any,
                         faces: Any) -> list[Any]:
        """The drawn wrinkles of a frame cast onto its large scale (``caster``: the mesh in the mocap frame)."""
        from .surface_wrinkles import SurfaceWrinkle

        by_name = {c.name: c for c in cameras}
        V = np.asarray(face_vertices, dtype=np.float64)
        F = np.asarray(faces, dtype=np.int64)
        out = []
        for drawn in self.drawn_at(mocap_frame):
            if drawn.camera not in by_name:
                raise InputError(f"a drawn wrinkle names camera {drawn.camera!r}; the cameras are "
                                 f"{', '.join(by_name)}")
            hits = caster.cast_pixels(by_name[drawn.camera], drawn.curve_px)
            if hits.hit.sum() < 2:
                # the head may turn away for a few frames of a long range: those frames go without it
                warnings.warn(f"drawn wrinkle {drawn.name!r}: its curve misses the face in camera "
                              f"{drawn.camera!r} at mocap frame {mocap_frame:g}; left out there", FacecapWarning,
                              stacklevel=2)
                continue
            tri, bary = hits.triangle[hits.hit], hits.barycentric[hits.hit]
            points = np.einsum("kj,kjc->kc", bary, V[F[tri]])
            arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
            s = arc / max(arc[-1], 1e-12)
            ease = np.clip(np.minimum(s, 1.0 - s) / _END_EASE, 0.0, 1.0)
            ease = ease * ease * (3.0 - 2.0 * ease)
            k = len(points)
            out.append(SurfaceWrinkle(f"{drawn.camera}:{drawn.name}", -1, points, np.full(k, drawn.width_mm),
                                      drawn.depth_mm * ease, np.ones(k)))
        return out


def _frames(value: Any, where: str) -> tuple[float, float] | None:
    if value is None:
        return None
    try:
        first, last = (float(v) for v in value)
    except (TypeError, ValueError):
        raise InputError(f"{where}: 'frames' must be [first, last] mocap frames") from None
    if not (np.isfinite(first) and np.isfinite(last)) or last < first:
        raise InputError(f"{where}: 'frames' must be [first, last] with first <= last")
    return first, last


def _positive(entry: Mapping[str, Any], key: str, where: str, *, allow_zero: bool = False) -> float:
    try:
        value = float(entry[key])
    except KeyError:
        raise InputError(f"{where}: '{key}' is missing") from None
    except (TypeError, ValueError):
        raise InputError(f"{where}: '{key}' must be a number") from None
    if not np.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise InputError(f"{where}: '{key}' must be {'>= 0' if allow_zero else '> 0'}, got {value}")
    return value


def read_wrinkle_edits(source: str | os.PathLike[str] | Mapping[str, Any]) -> WrinkleEdits:
    """Read an edit file (or its parsed content) into :class:`WrinkleEdits`.

    Raises
    ------
    InputError
        Naming the file and the entry, on anything but the documented form.
    """
    path = None
    if isinstance(source, Mapping):
        doc: Any = source
    else:
        path = Path(source)
        try:
            doc = json.loads(path.read_text())
        except json.JSONDecodeError as exc:
            raise InputError(f"not JSON ({exc.msg}, line {exc.lineno})", path=str(path)) from None
    where = str(path) if path is not None else "edits"
    try:
        if not isinstance(doc, Mapping) or set(doc) - {"depth", "add"}:
            raise InputError("expected an object with 'depth' and/or 'add' lists")
        depth = []
        for i, entry in enumerate(doc.get("depth", [])):
            at = f"depth[{i}]"
            wrinkles = entry.get("wrinkles")
            if wrinkles is not None and (isinstance(wrinkles, str) or not all(isinstance(w, str) for w in wrinkles)):
                raise InputError(f"{at}: 'wrinkles' must be a list of identities like 'cam_left:2'")
            depth.append(DepthEdit(_positive(entry, "scale", at, allow_zero=True),
                                   None if wrinkles is None else tuple(wrinkles), _frames(entry.get("frames"), at)))
        add = []
        for i, entry in enumerate(doc.get("add", [])):
            at = f"add[{i}]"
            if not isinstance(entry.get("camera"), str):
                raise InputError(f"{at}: 'camera' (the image the curve is drawn in) is missing")
            given = [k for k in ("curve_px", "svg_path", "svg_file") if k in entry]
            if len(given) != 1:
                raise InputError(f"{at}: give exactly one of 'curve_px', 'svg_path' or 'svg_file'")
            if given[0] == "curve_px":
                curve = np.asarray(entry["curve_px"], dtype=np.float64)
                if curve.ndim != 2 or curve.shape[1] != 2 or len(curve) < 2 or not np.isfinite(curve).all():
                    raise InputError(f"{at}: 'curve_px' must be at least two [x, y] pixel points")
            elif given[0] == "svg_path":
                curve = svg_path_points(str(entry["svg_path"]))
            else:
                svg = Path(entry["svg_file"])
                if not svg.is_absolute() and path is not None:
                    svg = path.parent / svg
                paths = [e for e in ElementTree.parse(svg).iter() if e.tag.rsplit("}", 1)[-1] == "path"]
                if not paths or not paths[0].get("d"):
                    raise InputError(f"{at}: {svg} holds no <path d=...>")
                curve = svg_path_points(paths[0].get("d", ""))
            add.append(DrawnWrinkle(entry["camera"], curve, _positive(entry, "depth_mm", at),
                                    _positive(entry, "width_mm", at), _frames(entry.get("frames"), at),
                                    str(entry.get("name", f"drawn_{i}"))))
    except InputError as exc:
        if path is not None and exc.path is None:
            raise InputError(exc.message, path=str(path)) from None
        raise
    except (AttributeError, TypeError, ElementTree.ParseError) as exc:
        raise InputError(f"{where}: malformed edit ({exc})") from None
    return WrinkleEdits(tuple(depth), tuple(add))
