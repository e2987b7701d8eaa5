"""Headless PNG pictures of a triangle mesh, grey-shaded or coloured by a per-vertex value.

matplotlib's Agg canvas draws the triangles as one ``PolyCollection`` in
back-to-front order (painter's algorithm) after back-face culling: no OpenGL,
no display, and no pyplot global state (a :class:`matplotlib.figure.Figure`
with its own ``FigureCanvasAgg``), so it runs on any server.
"""

from __future__ import annotations

import os
import textwrap
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.collections import PolyCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from ..errors import InputError
from ..io.atomic_write import atomic_path
from ..validate import as_faces, as_vertices

__all__ = ["render_mesh", "render_side_by_side", "MeshPanel", "draw_mesh", "as_size_px"]

View = str | tuple[float, float]

_SKIN_GREY = np.array([0.80, 0.77, 0.75])
"""Base albedo of the grey render (a light, slightly warm grey)."""
_AMBIENT = 0.25
"""Ambient share of the shading; the rest is Lambert from the light."""
_NAN_GREY = np.array([0.62, 0.62, 0.62])
"""Colour of faces whose value is NaN (e.g. vertices left out of an evaluation)."""
_BACKGROUND = (1.0, 1.0, 1.0)
_DPI = 100.0
_COLORBAR_FRACTION = 0.14
"""Share of the image width given to the colour bar strip when values are drawn."""
_TITLE_FRACTION = 0.07
"""Share of the image height given to a panel title (and to the figure title)."""
_MARGIN = 0.04
"""Blank border around the mesh, as a share of its projected extent."""
_CAPTION_LINE_PX = 19
"""Height of one caption line (11 pt text at 100 dpi, with its leading)."""


class MeshPanel(NamedTuple):
    """One panel of :func:`render_side_by_side`.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Vertex positions.
    F : (m, 3) int64 array
        Triangles, counter-clockwise seen from outside.
    values : (n,) float array or None
        Per-vertex value to colour by (NaN drawn grey); None for a grey render.
    title : str or None
        Panel title.
    """

    V: Any
    F: Any
    values: Any = None
    title: str | None = None


def _camera(view: View) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Screen right, screen up and toward-camera unit vectors of an orthographic view."""
    if isinstance(view, str):
        key = view.strip().lower()
        presets = {"front": (0.0, 0.0), "side": (90.0, 0.0), "left": (90.0, 0.0), "right": (-90.0, 0.0)}
        if key not in presets:
            raise InputError(
                f"view: expected 'front', 'side' or an (azimuth_deg, elevation_deg) pair, got {view!r}"
            )
        azim, elev = presets[key]
    else:
        try:
            azim, elev = (float(x) for x in view)
        except (TypeError, ValueError):
            raise InputError(
                f"view: expected 'front', 'side' or an (azimuth_deg, elevation_deg) pair, got {view!r}"
            ) from None
        if not (np.isfinite(azim) and np.isfinite(elev)) or abs(elev) >= 90.0:
            raise InputError(f"view: expected finite angles with |elevation| < 90 degrees, got {view!r}")
    a, e = np.radians(azim), np.radians(elev)
    toward = np.array([np.sin(a) * np.cos(e), np.sin(e), np.cos(a) * np.cos(e)])
    right = np.array([np.cos(a), 0.0, -np.sin(a)])
    up = np.cross(toward, right)
    return right, up, toward


def _check_values(values: Any, n: int, *, name: str) -> np.ndarray | None:
    if values is None:
        return None
    x = np.asarray(values, dtype=np.float64)
    if x.shape != (n,):
        raise InputError(f"{name}: expected one value per vertex, shape ({n},), got {x.shape}")
    if np.any(np.isinf(x)):
        raise InputError(f"{name}: contains infinite values (use NaN for 'no value')")
    return x


def _project(V: np.ndarray, view: View) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    right, up, toward = _camera(view)
    return V @ right, V @ up, V @ toward


def _polygons(
    V: np.ndarray,
    F: np.ndarray,
    values: np.ndarray | None,
    view: View,
    norm: Normalize | None,
    cmap_name: str,
) -> tuple[np.ndarray, np.ndarray]:
    """Visible triangles in screen space, back to front, and their RGB colours."""
    right, up, toward = _camera(view)
    xs, ys, depth = V @ right, V @ up, V @ toward
    P = V[F]  # (m, 3, 3)
    normal = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    facing = normal @ toward
    keep = facing > 0.0  # back-face culling (counter-clockwise = front)
    Fk = F[keep]
    order = np.argsort(depth[Fk].mean(axis=1), kind="stable")  # far first
    Fk = Fk[order]
    tri = np.stack([xs[Fk], ys[Fk]], axis=-1)  # (k, 3, 2)
    if values is None:
        nk = normal[keep][order]
        nk = nk / np.linalg.norm(nk, axis=1, keepdims=True)
        light = toward + 0.35 * up + 0.25 * right  # a key light above-left of the camera
        light = light / np.linalg.norm(light)
        lambert = np.clip(nk @ light, 0.0, 1.0)
        shade = _AMBIENT + (1.0 - _AMBIENT) * lambert
        rgb = shade[:, None] * _SKIN_GREY[None, :]
    else:
        fv = values[Fk].mean(axis=1)
        rgb = np.empty((Fk.shape[0], 3))
        ok = np.isfinite(fv)
        rgb[ok] = colormaps[cmap_name](norm(fv[ok]))[:, :3]
        rgb[~ok] = _NAN_GREY
    return tri, rgb


def _screen_bounds(V: np.ndarray, view: View) -> tuple[float, float, float, float]:
    xs, ys, _ = _project(V, view)
    return float(xs.min()), float(xs.max()), float(ys.min()), float(ys.max())


def _draw(ax: Any, tri: np.ndarray, rgb: np.ndarray, bounds: Sequence[float], aspect_px: float) -> None:
    """Fill ``ax`` with the triangles; ``bounds`` grow to the axes' pixel aspect (equal scale)."""
    x0, x1, y0, y1 = (float(b) for b in bounds)
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    w, h = max(x1 - x0, 1e-12), max(y1 - y0, 1e-12)
    if w / h < aspect_px:
        w = h * aspect_px
    else:
        h = w / aspect_px
    ax.set_xlim(cx - 0.5 * w, cx + 0.5 * w)
    ax.set_ylim(cy - 0.5 * h, cy + 0.5 * h)
    ax.set_axis_off()
    ax.set_facecolor(_BACKGROUND)
    if tri.shape[0]:
        # Edges in the face colour close the hairline seams Agg leaves between triangles.
        pc = PolyCollection(
            tri, facecolors=rgb, edgecolors="none", linewidths=0.0, antialiaseds=False, closed=True
        )
        ax.add_collection(pc)


def as_size_px(size_px: Any, *, name: str = "size_px") -> tuple[int, int]:
    """A picture's size checked: ``(width, height)`` in whole pixels, each at least 16.

    Every picture function of ``report`` takes its size this way.

    Parameters
    ----------
    size_px : pair of int
        ``(width, height)`` in pixels; any two numbers ``int`` accepts (they are truncated).
    name : str, default 'size_px'
        The argument's name in the error message.

    Returns
    -------
    (int, int)
        Width and height in pixels.

    Raises
    ------
    InputError
        If ``size_px`` is not two numbers, or either is below 16 pixels.

    Examples
    --------
    >>> as_size_px((640.0, 480))
    (640, 480)
    """
    try:
        w, h = (int(s) for s in size_px)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected (width, height) in pixels, got {size_px!r}") from None
    if w < 16 or h < 16:
        raise InputError(f"{name}: expected at least 16 x 16 pixels, got {size_px!r}")
    return w, h


def _check_bounds(bounds: Any) -> tuple[float, float, float, float] | None:
    if bounds is None:
        return None
    try:
        b = tuple(float(x) for x in bounds)
    except (TypeError, ValueError):
        raise InputError(f"bounds: expected (xmin, xmax, ymin, ymax), got {bounds!r}") from None
    if len(b) != 4 or not all(np.isfinite(b)) or b[1] <= b[0] or b[3] <= b[2]:
        raise InputError(f"bounds: expected finite (xmin, xmax, ymin, ymax) with min < max, got {bounds!r}")
    return b  # type: ignore[return-value]


def _pad(bounds: Sequence[float]) -> tuple[float, float, float, float]:
    x0, x1, y0, y1 = bounds
    m = _MARGIN * max(x1 - x0, y1 - y0)
    return x0 - m, x1 + m, y0 - m, y1 + m


def _colorbar_extend(values: Sequence[np.ndarray], norm: Normalize) -> str:
    """Which ends of the colour bar get an arrow: the values that fall outside its range.

    Parameters
    ----------
    values : sequence of (n,) float arrays
        The values of every panel drawn with ``norm`` (NaN ignored).
    norm : matplotlib.colors.Normalize
        The colour range.

    Returns
    -------
    {'neither', 'min', 'max', 'both'}
        ``'max'`` when some value exceeds ``norm.vmax`` (those faces are drawn in the top
        colour, and the arrow says that the top colour means "this much or more").

    Examples
    --------
    >>> _colorbar_extend([np.array([0.0, 2.0, np.nan])], Normalize(0.0, 1.0))
    'max'
    """
    finite = [v[np.isfinite(v)] for v in values]
    above = any(v.size and float(v.max()) > norm.vmax for v in finite)
    below = any(v.size and float(v.min()) < norm.vmin for v in finite)
    return {(False, False): "neither", (True, False): "max", (False, True): "min", (True, True): "both"}[(above, below)]


def _save(fig: Figure, path: str | os.PathLike[str]) -> None:
    FigureCanvasAgg(fig)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=_DPI, facecolor=_BACKGROUND)


def render_side_by_side(
    panels: Sequence[MeshPanel | tuple[Any, ...]],
    path: str | os.PathLike[str],
    *,
    value_label: str | None = None,
    vmin: float | None = None,
    vmax: float | None = None,
    view: View = "front",
    title: str | None = None,
    cmap: str = "inferno",
    panel_size_px: tuple[int, int] = (600, 700),
    bounds: Sequence[float] | None = None,
    caption: str | None = None,
) -> Normalize | None:
    """Render several meshes in one PNG, side by side, framed and scaled alike.

    Typical use: ``[truth, result, error map]`` of one frame.

    Parameters
    ----------
    panels : sequence of MeshPanel or (V, F, values, title) tuples
        The meshes, left to right; see :class:`MeshPanel`.
    path : str or path-like
        PNG file to write (atomically: a temporary sibling renamed on success).
    value_label : str or None, optional
        Label of the shared colour bar, with units (e.g. ``'error (mm)'``).
    vmin, vmax : float or None, optional
        Colour range shared by every panel with values; default the finite
        minimum and maximum over those panels.
    view : {'front', 'side'} or (azimuth_deg, elevation_deg), optional
        Orthographic view, default ``'front'`` (camera on +z looking toward -z,
        y up); ``'side'`` puts the camera on +x; angles rotate the camera about
        +y (azimuth) and then raise it (elevation).
    title : str or None, optional
        Title over the whole picture.
    cmap : str, optional
        matplotlib colour map for the values, default ``'inferno'``.
    panel_size_px : (int, int), optional
        Width and height of each panel in pixels; the image is
        ``len(panels) * width`` (+ a colour-bar strip) by ``height`` (+ a title strip).
    bounds : (xmin, xmax, ymin, ymax) or None, optional
        Screen-space window (mm, in view coordinates) shown in every panel; default
        the union of the panels' projected extents plus a small margin. Fix it
        to keep the framing identical across frames of an animation.
    caption : str or None, optional
        Text under the panels (lines split at ``\\n`` and wrapped to the panels' width): what the
        panel titles' symbols mean, what the picture shows and why. Default None: no caption strip.

    Returns
    -------
    matplotlib.colors.Normalize or None
        The colour range every panel with values was drawn with (``vmin``, ``vmax``, mm or
        the values' unit); None when no panel has values. Values beyond it are drawn in the
        end colours and the colour bar gets an arrow at that end.

    Raises
    ------
    InputError
        If a panel's mesh, values or faces are invalid, or an option is out of range.
    """
    if len(panels) == 0:
        raise InputError("panels: expected at least one (V, F, values, title) panel")
    pw, ph = as_size_px(panel_size_px, name="panel_size_px")
    checked = []
    for k, p in enumerate(panels):
        p = MeshPanel(*p)
        V = as_vertices(p.V, name=f"panels[{k}].V")
        F = as_faces(p.F, V.shape[0], name=f"panels[{k}].F")
        vals = _check_values(p.values, V.shape[0], name=f"panels[{k}].values")
        checked.append((V, F, vals, p.title))
    any_values = any(c[2] is not None for c in checked)
    return _render(
        checked,
        path,
        value_label=value_label,
        vmin=vmin,
        vmax=vmax,
        view=view,
        title=title,
        cmap=cmap,
        panel_w=pw,
        panel_h=ph,
        cbar_w=int(round(_COLORBAR_FRACTION * pw / (1.0 - _COLORBAR_FRACTION))) if any_values else 0,
        title_h=int(round(_TITLE_FRACTION * ph)) if title else 0,
        ptitle_h=int(round(_TITLE_FRACTION * ph)) if any(c[3] for c in checked) else 0,
        bounds=bounds,
        caption=caption,
    )


def _render(
    checked: list[tuple[np.ndarray, np.ndarray, np.ndarray | None, str | None]],
    path: str | os.PathLike[str],
    *,
    value_label: str | None,
    vmin: float | None,
    vmax: float | None,
    view: View,
    title: str | None,
    cmap: str,
    panel_w: int,
    panel_h: int,
    cbar_w: int,
    title_h: int,
    ptitle_h: int,
    bounds: Sequence[float] | None,
    caption: str | None = None,
) -> Normalize | None:
    """Lay out validated panels in a figure of exactly the requested pixels, save it, return the colour range."""
    _camera(view)
    if cmap not in colormaps:
        raise InputError(f"cmap: unknown matplotlib colour map {cmap!r}")
    fixed = _check_bounds(bounds)
    pw, ph = panel_w, panel_h
    with_values = [c[2] for c in checked if c[2] is not None]
    norm = None
    if with_values:
        finite = np.concatenate([v[np.isfinite(v)] for v in with_values])
        lo = float(vmin) if vmin is not None else (float(finite.min()) if finite.size else 0.0)
        hi = float(vmax) if vmax is not None else (float(finite.max()) if finite.size else 1.0)
        if not (np.isfinite(lo) and np.isfinite(hi)):
            raise InputError(f"vmin, vmax: expected finite numbers, got {vmin!r}, {vmax!r}")
        if hi <= lo:
            if vmin is not None and vmax is not None:
                raise InputError(f"vmin, vmax: expected vmin < vmax, got {lo} and {hi}")
            hi = lo + 1.0  # constant values: any range shows them
        norm = Normalize(vmin=lo, vmax=hi)

    if fixed is None:
        bs = np.array([_screen_bounds(c[0], view) for c in checked])
        fixed = _pad((bs[:, 0].min(), bs[:, 1].max(), bs[:, 2].min(), bs[:, 3].max()))

    k = len(checked)
    # each caption line wrapped to the panels' width (11 pt text: at most about 8.5 px a character)
    caption_lines = [part for line in (caption.splitlines() if caption else [])
                     for part in (textwrap.wrap(line, width=max(20, int(k * pw / 8.5))) or [""])]
    cap_h = (len(caption_lines) + 1) * _CAPTION_LINE_PX if caption_lines else 0
    W, H = k * pw + cbar_w, ph + title_h + ptitle_h + cap_h
    fig = Figure(figsize=(W / _DPI, H / _DPI), dpi=_DPI, facecolor=_BACKGROUND)
    for i, (V, F, vals, ptitle) in enumerate(checked):
        ax = fig.add_axes((i * pw / W, cap_h / H, pw / W, ph / H))
        tri, rgb = _polygons(V, F, vals, view, norm if vals is not None else None, cmap)
        _draw(ax, tri, rgb, fixed, pw / ph)
        if ptitle:
            fig.text((i + 0.5) * pw / W, (cap_h + ph + 0.5 * ptitle_h) / H, ptitle, ha="center", va="center",
                     fontsize=12)
    if title:
        fig.text(0.5, 1.0 - 0.5 * title_h / H, title, ha="center", va="center", fontsize=14)
    if caption_lines:
        fig.text(0.5 * k * pw / W, 0.5 * cap_h / H, "\n".join(caption_lines), ha="center", va="center", fontsize=11,
                 linespacing=1.3)
    if norm is not None and cbar_w > 0:
        cax = fig.add_axes(((k * pw + 0.15 * cbar_w) / W, (cap_h + 0.1 * ph) / H, 0.2 * cbar_w / W, 0.8 * ph / H))
        sm = ScalarMappable(norm=norm, cmap=colormaps[cmap])
        cb = fig.colorbar(sm, cax=cax, extend=_colorbar_extend(with_values, norm))
        if value_label:
            cb.set_label(value_label)
    _save(fig, path)
    return norm


def render_mesh(
    V: Any,
    F: Any,
    path: str | os.PathLike[str],
    *,
    values: Any = None,
    value_label: str | None = None,
    vmin: float | None = None,
    vmax: float | None = None,
    view: View = "front",
    title: str | None = None,
    cmap: str = "inferno",
    size_px: tuple[int, int] = (800, 900),
    bounds: Sequence[float] | None = None,
) -> Normalize | None:
    """Render a triangle mesh to a PNG: grey-shaded, or coloured by a per-vertex value.

    Parameters
    ----------
    V : (n, 3) float64 array, mm
        Vertex positions.
    F : (m, 3) int64 array
        Triangles, counter-clockwise seen from outside (faces seen from
        behind are culled).
    path : str or path-like
        PNG file to write (atomically: a temporary sibling renamed on success).
    values : (n,) float array or None, optional
        Per-vertex value (e.g. error in mm) drawn as a heat map, each triangle
        the mean of its corners, unshaded so colours match the colour bar;
        NaN is drawn grey. Default None: a Lambert + ambient grey render.
    value_label : str or None, optional
        Colour-bar label with units, e.g. ``'error (mm)'``.
    vmin, vmax : float or None, optional
        Colour range; default the finite minimum and maximum of ``values``.
    view : {'front', 'side'} or (azimuth_deg, elevation_deg), optional
        Orthographic view; default ``'front'``: camera on +z looking toward -z
        with y up (the ICT face looks toward +z). ``'side'``: camera on +x.
        Angles rotate the camera about +y (azimuth) and then raise it (elevation).
    title : str or None, optional
        Title drawn above the mesh.
    cmap : str, optional
        matplotlib colour map, default ``'inferno'``.
    size_px : (int, int), optional
        Image width and height in pixels, default (800, 900); the image has
        exactly this size. With ``values`` the rightmost 14 % holds the colour
        bar, with ``title`` the top 7 % the title; the mesh fills the rest.
    bounds : (xmin, xmax, ymin, ymax) or None, optional
        Screen-space window (mm, in view coordinates: x right, y up) to show,
        grown to the panel's aspect ratio; default the mesh's projected extent
        plus a 4 % margin. Fix it to frame every frame of an animation alike.

    Returns
    -------
    matplotlib.colors.Normalize or None
        The colour range of ``values`` as drawn (values beyond it in the end colours, with an
        arrow on the colour bar); None without ``values``.

    Raises
    ------
    InputError
        If the mesh, values or an option is invalid (MeshError for the mesh).

    Notes
    -----
    Painter's algorithm: triangles facing away from the camera are dropped
    (:math:`n \\cdot d \\le 0` with :math:`n = (v_1 - v_0) \\times (v_2 - v_0)` and
    :math:`d` the unit vector toward the camera), the rest are sorted by the
    depth of their centroid and drawn far to near. This is exact for convex
    regions and good for a face seen from the front; intersecting or deeply
    interleaved triangles may show ordering artefacts. A 10k-vertex,
    18k-triangle mesh renders in well under a second.

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    >>> F = np.array([[0, 1, 2], [0, 2, 3]])
    >>> out = os.path.join(tempfile.mkdtemp(), "quad.png")
    >>> render_mesh(V, F, out, size_px=(64, 64)) is None  # no values, no colour range
    True
    >>> os.path.getsize(out) > 0
    True
    """
    w, h = as_size_px(size_px)
    Vc = as_vertices(V, name="V")
    Fc = as_faces(F, Vc.shape[0], name="F")
    vals = _check_values(values, Vc.shape[0], name="values")
    cbar_w = int(round(_COLORBAR_FRACTION * w)) if vals is not None else 0
    title_h = int(round(_TITLE_FRACTION * h)) if title else 0
    return _render(
        [(Vc, Fc, vals, None)],
        path,
        value_label=value_label,
        vmin=vmin,
        vmax=vmax,
        view=view,
        title=title,
        cmap=cmap,
        panel_w=w - cbar_w,
        panel_h=h - title_h,
        cbar_w=cbar_w,
        title_h=title_h,
        ptitle_h=0,
        bounds=bounds,
    )


def draw_mesh(ax: Any, V: Any, F: Any, *, view: View = "front", bounds: Sequence[float] | None = None,
              aspect_px: float = 1.0) -> tuple[float, float, float, float]:
    """Draw a grey-shaded mesh into a matplotlib axes, for pictures that add their own marks on top.

    The same painter's-algorithm render as :func:`render_mesh` (back faces culled, Lambert plus
    ambient), drawn into ``ax`` with the axes' limits set to ``bounds`` grown to ``aspect_px``.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        The axes to draw into (axis lines are turned off).
    V : (n, 3) float64 array, mm
        Vertex positions.
    F : (m, 3) int64 array
        Triangles, counter-clockwise seen from outside.
    view : {'front', 'side'} or (azimuth_deg, elevation_deg), optional
        As for :func:`render_mesh`; screen x is ``V @ right``, screen y ``V @ up``.
    bounds : (xmin, xmax, ymin, ymax) or None, optional
        Screen-space window, mm; default the mesh's projected extent plus a 4 % margin.
    aspect_px : float, default 1.0
        Width over height of the axes in pixels, so that a millimetre is as long across as up.

    Returns
    -------
    (xmin, xmax, ymin, ymax)
        The window drawn, before it was grown to the aspect.

    Raises
    ------
    InputError
        If the mesh, the view or the bounds are invalid (MeshError for the mesh).
    """
    Vc = as_vertices(V, name="V")
    Fc = as_faces(F, Vc.shape[0], name="F")
    window = _check_bounds(bounds) or _pad(_screen_bounds(Vc, view))
    tri, rgb = _polygons(Vc, Fc, None, view, None, "inferno")
    _draw(ax, tri, rgb, window, float(aspect_px))
    return window
