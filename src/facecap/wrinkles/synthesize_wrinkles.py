"""Wrinkles synthesised on the large-scale face: valleys imposed, bulges by the nonlinear shell (5.3).

Bickel et al. (2007), section 5.3, for one frame:

1. each valley line (:class:`~facecap.wrinkles.surface_wrinkles.SurfaceWrinkle`)
   gives the vertices within its half-width ``w`` an absolute position: the
   large-scale vertex offset along the smoothed normal by the cross-section
   ``S(w, d, p)`` at its distance ``p`` from the line (the model the
   cross-sections were fitted with, :func:`~facecap.wrinkles.cross_section`);
2. the vertices within ``influence_widths * w`` of a valley line are the
   wrinkles' influence; overlapping influences merge into regions (connected
   pieces of the mesh), "an automatic segmentation of the face into wrinkling
   and non-wrinkling areas";
3. in each region independently the discrete shell of eq. 8
   (:mod:`~facecap.wrinkles.discrete_shell`) is minimised over the region's
   vertices outside the valleys, from the large scale, everything else fixed.
   Its rest state is the frame's large-scale surface (a choice, see below).
   Keeping the valleys' length and the surface's curvature pushes the skin up
   beside them: the bulges.

**Rest state.** The paper measures the shell against "the initial mesh F",
which in the same section is also "the linearly deformed face F". Here it is
the frame's large-scale result: the large scale is already the minimiser of its
own stretching and bending under the markers, and a neutral rest state would
let each region undo that deformation where there is no wrinkle at all (the
regions have no markers). With the large scale as rest state, a frame without
wrinkles is returned unchanged, exactly.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..errors import InputError
from ..mesh.nearest_on_polyline import nearest_on_polyline
from ..mesh.vertex_normals import face_normals
from ..typing import BoolArray, FloatArray, IntArray
from ..validate import as_faces, as_vertices
from .cross_section import cross_section
from .discrete_shell import AREA, BEND, STRETCH, DiscreteShell, minimize_shell
from .fit_cross_sections import DEFAULT_ROUNDING
from .surface_wrinkles import SurfaceWrinkle, identity_parts

__all__ = ["WrinkleSynthesis", "synthesize_wrinkles", "smoothed_normals", "wrinkle_depth_scale"]

INFLUENCE_WIDTHS = 2.0
"""The shell moves the skin up to this many half-widths from a valley line (the paper's "maximum influence
distance", relative to each wrinkle's own width). Measured on the tuning take (seed 0): with the truth's
curves, 3.5 moved skin 0.27 mm outside the truth's wrinkle support, 2.5 moved it 0.035 mm, with the same error;
from the footage, where widths come out up to 30 % wide, 2.5 moved it 0.09 mm and 2.0 0.03 mm, the error
over the wrinkles unchanged (0.46-0.48 of the wrinkles' own)."""
SHELL_LENGTH_MM = 10.0
"""The unit the paper's constants are read in (``length_mm`` of the shell): 1 cm. Chosen by measurement on
the generator's truth curves (seed 0, 148k vertices): read in mm (``length_mm=1``) the membrane terms are
100-1000x the bending one, the free skin barely rises (bulges -0.02 mm against the truth's +0.056 mm) and the
error over the wrinkles is 0.103 of the wrinkle's (0.098 with no shell at all); read in cm, bulges +0.046 mm,
error 0.069. The paper does not state its unit."""


class WrinkleSynthesis(NamedTuple):
    """One frame with its wrinkles.

    Attributes
    ----------
    vertices : (n, 3) float64 array, mm
        The large scale with the wrinkles.
    valley : (n,) bool array
        Vertices given a position by a valley (the shell's constraints).
    region : (n,) int64 array
        Influence region per vertex (-1 outside every region).
    n_regions : int
    shell_energy : (n_regions,) float64 array
        Eq. 8 per region after the minimisation (before: ``initial_energy``).
    initial_energy : (n_regions,) float64 array
    iterations : (n_regions,) int64 array
    """

    vertices: FloatArray
    valley: BoolArray
    region: IntArray
    n_regions: int
    shell_energy: FloatArray
    initial_energy: FloatArray
    iterations: IntArray


def smoothed_normals(V: Any, F: Any, *, iterations: int = 3, vertices: Any = None) -> FloatArray:
    """Area-weighted vertex normals averaged over their one-ring ``iterations`` times (unit, (n, 3)).

    The smoothing keeps the offsets of neighbouring valley vertices parallel on a finely meshed, slightly
    noisy scan ("offset ... along their (smoothed) normals", 5.3). ``vertices``: compute only near these.
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    if vertices is not None:
        near = np.zeros(len(V), dtype=bool)
        near[np.asarray(vertices)] = True
        for _ in range(iterations + 1):
            near[F[near[F].any(axis=1)].ravel()] = True
        F = F[near[F].all(axis=1)]
    n_face = face_normals(V, F)
    N = np.zeros_like(V)
    for i in range(3):
        np.add.at(N, F[:, i], n_face)
    if iterations:
        rows = np.concatenate([F[:, 0], F[:, 1], F[:, 2], F[:, 1], F[:, 2], F[:, 0]])
        cols = np.concatenate([F[:, 1], F[:, 2], F[:, 0], F[:, 0], F[:, 1], F[:, 2]])
        A = sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(V), len(V)))
        A.data[:] = 1.0
        A = A + sp.identity(len(V), format="csr")
        for _ in range(iterations):
            N = A @ (N / np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300))
    length = np.linalg.norm(N, axis=1, keepdims=True)
    return np.divide(N, length, out=np.zeros_like(N), where=length > 0)


def wrinkle_depth_scale(wrinkle: SurfaceWrinkle, depth_scale: float | Mapping[str, float]) -> float:
    """The factor on a wrinkle's depth that :func:`synthesize_wrinkles`'s ``depth_scale`` gives it.

    Parameters
    ----------
    wrinkle : SurfaceWrinkle
        The wrinkle; only its identity (``wrinkle.wrinkle``) is read.
    depth_scale : float or mapping of str to float
        One factor for every wrinkle, or factors by identity: a mapping names the wrinkle by its
        full (merged) identity or by any camera's part of it (:func:`identity_parts`); the full
        name wins, the parts' factors multiply, and a wrinkle it does not name keeps 1.

    Returns
    -------
    float
        The factor (dimensionless).

    Examples
    --------
    >>> w = SurfaceWrinkle("cam_left:2+cam_right:1", 0, np.zeros((2, 3)), *3 * [np.ones(2)])
    >>> wrinkle_depth_scale(w, {"cam_left:2": 0.5, "cam_right:1": 3.0, "cam_left:7": 9.0})
    1.5
    """
    if not isinstance(depth_scale, Mapping):
        return float(depth_scale)
    if wrinkle.wrinkle in depth_scale:
        return float(depth_scale[wrinkle.wrinkle])
    return float(np.prod([float(depth_scale[p]) for p in identity_parts(wrinkle.wrinkle) if p in depth_scale]))


def synthesize_wrinkles(large_scale: Any, faces: Any, wrinkles: Sequence[SurfaceWrinkle], *,
                        influence_widths: float = INFLUENCE_WIDTHS, rounding: float = DEFAULT_ROUNDING,
                        depth_scale: float | Mapping[str, float] = 1.0, stretch: float = STRETCH,
                        bend: float = BEND, area: float = AREA, length_mm: float = SHELL_LENGTH_MM, shell: bool = True,
                        motion: str = "normal", segment: bool = True, iterations: int = 20,
                        backend: str = "auto") -> WrinkleSynthesis:
    """Add the valleys and bulges of ``wrinkles`` to one large-scale frame.

    Parameters
    ----------
    large_scale : (n, 3) float array, mm
        The frame of ``facecap animate`` (the face's frame).
    faces : (f, 3) int array
    wrinkles : sequence of SurfaceWrinkle
        Valley lines on ``large_scale``, with width and depth along them.
    influence_widths : float, default :data:`INFLUENCE_WIDTHS`
    rounding : float, default 2
        The cross-section's rounded bottom (:func:`~facecap.wrinkles.cross_section`); use the value the
        cross-sections were fitted with.
    depth_scale : float or mapping of str to float, default 1
        Scale every valley's depth, or chosen ones by identity, full or any camera's part
        (section 6.2's editing).
    stretch, bend, area : float, default 300, 2, 30,000
        The shell's constants (:class:`~facecap.wrinkles.discrete_shell.DiscreteShell`), the paper's.
    length_mm : float, default :data:`SHELL_LENGTH_MM`
        The unit they are read in.
    shell : bool, default True
        Minimise eq. 8 in each region; False leaves the imposed valleys only (no bulges).
    motion : {'normal', 'free'}, default 'normal'
        How the shell's free vertices move: along their smoothed normals only (a height field on the large
        scale, one unknown per vertex), or freely in 3D (the large scale's tangential placement, which the
        markers fixed, then slides too).
    segment : bool, default True
        Solve each influence region on its own (the paper's heuristic); False solves one global problem
        over every vertex but the valleys (the baseline the regions are measured against).
    iterations : int, default 20
        Gauss-Newton steps per region at most.
    backend : {'auto', 'pardiso', 'scipy'}, default 'auto'

    Returns
    -------
    WrinkleSynthesis

    Raises
    ------
    InputError
        On bad arrays or options.
    """
    V = as_vertices(large_scale, name="large_scale")
    F = as_faces(faces, len(V), name="faces")
    if motion not in ("normal", "free"):
        raise InputError(f"motion: expected 'normal' or 'free', got {motion!r}")
    if not np.isfinite(influence_widths) or influence_widths <= 1.0:
        raise InputError(f"influence_widths: expected a number > 1 (the valley is 1 width), got {influence_widths!r}")
    n = len(V)
    offset = np.zeros(n)
    valley = np.zeros(n, dtype=bool)
    influence = np.zeros(n, dtype=bool)
    tree = cKDTree(V)
    for wrinkle in wrinkles:
        scale = wrinkle_depth_scale(wrinkle, depth_scale)
        depth = np.clip(wrinkle.depth * scale, 0.0, None)
        if len(wrinkle.points) < 2 or not (depth > 0).any():
            continue
        reach = influence_widths * float(wrinkle.width.max())
        step = float(np.linalg.norm(np.diff(wrinkle.points, axis=0), axis=1).max())
        lists = tree.query_ball_point(wrinkle.points, reach + step)
        near = np.unique(np.concatenate([np.asarray(x, dtype=np.int64) for x in lists]))
        if near.size == 0:
            continue
        dist, foot = nearest_on_polyline(V[near], wrinkle.points)
        arc = wrinkle.arc_length
        w = np.interp(foot, arc, wrinkle.width)
        d = np.interp(foot, arc, depth)
        influence[near[dist < influence_widths * w]] = True
        inside = (dist < w) & (d > 0)
        if not inside.any():
            continue
        s = cross_section(dist[inside], w[inside], d[inside], rounding=rounding)
        rows = near[inside]
        deeper = s < offset[rows]  # crossing valleys: the deeper one holds
        offset[rows[deeper]] = s[deeper]
        valley[rows] = True
    out = V.copy()
    region = np.full(n, -1, dtype=np.int64)
    if not valley.any():
        empty = np.zeros(0)
        return WrinkleSynthesis(out, valley, region, 0, empty, empty, np.zeros(0, dtype=np.int64))
    influence |= valley
    if not segment:
        influence[:] = True
    normals = smoothed_normals(V, F, vertices=np.flatnonzero(influence))
    out[valley] += offset[valley, None] * normals[valley]
    # regions: connected pieces of the influence over the mesh's edges
    inside_faces = F[influence[F].any(axis=1)]
    edges = np.concatenate([inside_faces[:, [0, 1]], inside_faces[:, [1, 2]], inside_faces[:, [2, 0]]])
    keep = influence[edges].all(axis=1)
    graph = sp.csr_matrix((np.ones(int(keep.sum())), (edges[keep, 0], edges[keep, 1])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    members = np.flatnonzero(influence)
    _, region[members] = np.unique(labels[members], return_inverse=True)
    n_regions = int(region.max()) + 1
    energy = np.zeros(n_regions)
    initial = np.zeros(n_regions)
    steps = np.zeros(n_regions, dtype=np.int64)
    if shell:
        for k in range(n_regions):
            in_region = region == k
            # the region's triangles and one ring of fixed triangles round it (its boundary's curvature)
            sub_faces = F[in_region[F].any(axis=1)]
            # a scan's zero-area triangles have no rest shape for the shell to keep: left out of its terms
            doubled_area = np.linalg.norm(np.cross(V[sub_faces[:, 1]] - V[sub_faces[:, 0]],
                                                   V[sub_faces[:, 2]] - V[sub_faces[:, 0]]), axis=1)
            sub_faces = sub_faces[doubled_area > 1e-10 * max(float(doubled_area.max()), 1e-300)]
            used = np.unique(sub_faces)
            local = np.full(n, -1, dtype=np.int64)
            local[used] = np.arange(used.size)
            model = DiscreteShell(V[used], local[sub_faces], stretch=stretch, bend=bend, area=area,
                                  length_mm=length_mm)
            free = in_region[used] & ~valley[used]
            found = minimize_shell(model, out[used], free, iterations=iterations, backend=backend,
                                   directions=normals[used] if motion == "normal" else None)
            out[used[free]] = found.vertices[free]
            energy[k], initial[k], steps[k] = found.energy, found.initial_energy, found.iterations
    return WrinkleSynthesis(out, valley, region, n_regions, energy, initial, steps)
