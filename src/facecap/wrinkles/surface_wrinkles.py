"""Tracked wrinkles carried from the images onto the animated surface, and the two cameras' views merged.

Section 5.3 of Bickel et al. (2007): the large-scale mesh is mapped into the
mocap frame (where the cameras are calibrated), each 2D valley spline is cast
onto it through its camera, and the hits are carried back to the face by their
triangle and barycentric coordinates, which do not depend on the frame the mesh
is in. Depth and width come from the cross-sections of 5.2 along the spline.
A wrinkle both cameras track is merged "by simple snapping and linear blending".
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from ..mesh.nearest_on_polyline import nearest_on_polyline
from ..typing import FloatArray

__all__ = ["SurfaceWrinkle", "wrinkles_on_surface", "anchor_curves", "merge_camera_wrinkles", "identity_parts",
           "names_wrinkle"]

SNAP_MM = 2.5
"""Two cameras' curves of one paint closer than this (mean, over their overlap) are one wrinkle."""


class SurfaceWrinkle(NamedTuple):
    """One wrinkle's valley line on the face at one frame.

    Attributes
    ----------
    wrinkle : str
        Identity: ``'<camera>:<tracker id>'``, or the cameras' identities, sorted, joined by ``'+'``
        once merged (which cameras see a wrinkle may change from frame to frame: match a part,
        :func:`names_wrinkle`).
    color : int
        Paint index.
    points : (k, 3) float64 array, mm
        The valley line on the large-scale face (the face's frame, as the result stores it).
    width : (k,) float64 array, mm
        Half-width ``w`` (valley line to the zero crossing) at each point.
    depth : (k,) float64 array, mm
        Valley depth ``d`` (0 where the cross-sections found no wrinkle).
    quality : (k,) float64 array
        How squarely the camera saw each point (``cos^2`` of the angle between the view ray and the
        surface normal), the weight of the linear blending.
    """

    wrinkle: str
    color: int
    points: FloatArray
    width: FloatArray
    depth: FloatArray
    quality: FloatArray

    @property
    def arc_length(self) -> FloatArray:
        """Arc length from the first point (k,), mm."""
        return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(self.points, axis=0), axis=1))])


def identity_parts(identity: str) -> list[str]:
    """The per-camera identities of a (merged) wrinkle: ``'cam_left:2+cam_right:1'`` -> both."""
    return identity.split("+")


def names_wrinkle(identity: str, names: Any) -> bool:
    """Whether ``names`` (a collection of identities) names this wrinkle: its merged name or any camera's part."""
    return identity in names or any(part in names for part in identity_parts(identity))


def _merged_identity(a: str, b: str) -> str:
    """One name for a wrinkle several cameras saw, whichever saw it best: the parts sorted."""
    return "+".join(sorted(set(identity_parts(a)) | set(identity_parts(b))))


def _cameras_of(identity: str) -> set[str]:
    return {part.rsplit(":", 1)[0] for part in identity_parts(identity)}


def _median3(x: FloatArray) -> FloatArray:
    """Running median of three (ends kept): one outlying cross-section does not dent the valley."""
    if len(x) < 3:
        return x
    y = x.copy()
    y[1:-1] = np.median(np.stack([x[:-2], x[1:-1], x[2:]]), axis=0)
    return y


def wrinkles_on_surface(curves_px: Sequence[Any], cross_sections: Any, camera: Any, caster: Any,
                        face_vertices: Any, faces: Any, *, identities: Sequence[str] | None = None,
                        colors: Sequence[int] | None = None, anchors: Sequence[Any] | None = None,
                        min_points: int = 4) -> list[SurfaceWrinkle]:
    """One camera's valley curves and cross-sections at one frame, as lines on the face.

    Parameters
    ----------
    curves_px : sequence of (m, 2) arrays, px
        The valley polylines in the image (``TrackedWrinkle.curve()``), the ones the cross-sections
        were fitted along, in the same order.
    cross_sections : facecap.wrinkles.CrossSections
        :func:`~facecap.wrinkles.fit_cross_sections` of this image along ``curves_px``.
    camera : facecap.cameras.Camera
    caster : facecap.cameras.RayCaster
        The frame's large-scale mesh in the camera's (mocap) frame.
    face_vertices : (n, 3) float array, mm
        The same mesh in the face's frame (same vertex order and ``faces``).
    faces : (f, 3) int array
    identities : sequence of str, optional
        Per curve (default ``'<camera>:<i>'``).
    colors : sequence of int, optional
        Paint index per curve (default 0).
    anchors : sequence of (triangles (k,), barycentric (k, 3)[, rest depth (k,)]) or None, optional
        Per curve, where its valley line lies on the mesh (e.g. the painted stripe cast at the first
        frame, :func:`anchor_curves`): the line then rides with the mesh's skin and this frame's curve
        only places its cross-sections along it. A third array is the depth the rest frame's own
        shading already showed along the line (the scan holds that crease): it is subtracted. None (per
        curve or for all): cast this frame's curve onto the mesh (the paper's projection).
    min_points : int, default 4
        A curve with fewer surface hits is left out (it ran off the face).

    Returns
    -------
    list of SurfaceWrinkle
        Curves without a single cross-section are kept with depth 0.
    """
    V = np.asarray(face_vertices, dtype=np.float64)
    F = np.asarray(faces, dtype=np.int64)
    M = np.asarray(caster.V, dtype=np.float64)  # the same mesh in the mocap frame
    fit, samples = cross_sections.fit, cross_sections.samples
    out = []
    for i, curve in enumerate(curves_px):
        curve = np.asarray(curve, dtype=np.float64)
        anchor = None if anchors is None else anchors[i]
        if anchor is None:
            hits = caster.cast_pixels(camera, curve)
            ok = hits.hit
            if ok.sum() < min_points:
                continue
            tri, bary = hits.triangle[ok], hits.barycentric[ok]
        else:
            tri, bary = np.asarray(anchor[0]), np.asarray(anchor[1])
        points = np.einsum("kj,kjc->kc", bary, V[F[tri]])
        seen_at = np.einsum("kj,kjc->kc", bary, M[F[tri]])
        n_tri = np.cross(M[F[tri, 1]] - M[F[tri, 0]], M[F[tri, 2]] - M[F[tri, 0]])
        n_tri /= np.maximum(np.linalg.norm(n_tri, axis=1, keepdims=True), 1e-300)
        view = seen_at - camera.centre
        view /= np.linalg.norm(view, axis=1, keepdims=True)
        quality = np.einsum("kc,kc->k", view, n_tri) ** 2
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
        pixels = camera.project(seen_at).pixels
        mine = np.flatnonzero(samples.curve == i)
        width = np.full(len(points), 1.0)
        depth = np.zeros(len(points))
        finite = mine[np.isfinite(fit.width[mine]) & np.isfinite(fit.depth[mine])]
        if finite.size:
            # each cross-section at the line's point it sees nearest in the image
            nearest = np.argmin(np.linalg.norm(pixels[None] - samples.centres_px[finite][:, None], axis=2), axis=1)
            order = np.argsort(arc[nearest], kind="stable")
            at = arc[nearest][order]
            found = fit.has_wrinkle[finite][order]
            d = np.where(found, fit.depth[finite][order], 0.0)
            depth = np.interp(arc, at, _median3(d))
            if found.any():
                # the width of a cross-section without a wrinkle means nothing (often pinned at the fit's
                # bound): widths come from the detected ones only, or a shallow valley next to a
                # non-detection would be interpolated wide
                width = np.interp(arc, at[found], _median3(fit.width[finite][order][found]))
        if anchor is not None and len(anchor) > 2:
            depth = np.clip(depth - np.asarray(anchor[2]), 0.0, None)
        name = identities[i] if identities is not None else f"{camera.name}:{i}"
        color = int(colors[i]) if colors is not None else 0
        out.append(SurfaceWrinkle(name, color, points, width, depth, quality))
    return out


def anchor_curves(curves_px: Sequence[Any], camera: Any, caster: Any, *, min_points: int = 4) -> list[Any]:
    """Where each image curve lies on the mesh: (triangles (k,), barycentric (k, 3)), or None if it misses.

    Cast once, at a frame where the large scale is accurate (the first, neutral one, where the paint was
    masked), these are the valley lines as points of the skin: :func:`wrinkles_on_surface` carries them with
    the mesh to every later frame.
    """
    out: list[Any] = []
    for curve in curves_px:
        hits = caster.cast_pixels(camera, np.asarray(curve, dtype=np.float64))
        ok = hits.hit
        out.append((hits.triangle[ok], hits.barycentric[ok]) if ok.sum() >= min_points else None)
    return out


def _blend_pair(base: SurfaceWrinkle, other: SurfaceWrinkle, snap_mm: float) -> SurfaceWrinkle:
    """``other`` snapped onto ``base``: blended where they overlap, its overhangs appended at the ends."""
    dist, foot = nearest_on_polyline(other.points, base.points)
    arc_b = base.arc_length
    # where base's points lie on the other's line: blend them there with the other's values
    dist_b, foot_b = nearest_on_polyline(base.points, other.points)
    arc_o = other.arc_length
    # base points beside the other line, not past its ends (there the nearest point is its end, which would
    # pull them back along the line)
    over_b = (dist_b < snap_mm) & (foot_b > 1e-9) & (foot_b < arc_o[-1] - 1e-9)
    P = base.points.copy()
    W, D, Q = base.width.copy(), base.depth.copy(), base.quality.copy()
    if over_b.any():
        oq = np.interp(foot_b[over_b], arc_o, other.quality)
        # the other's weight eases in over snap_mm from its ends: no step where its line stops
        ease = np.clip(np.minimum(foot_b[over_b], arc_o[-1] - foot_b[over_b]) / snap_mm, 0.0, 1.0)
        weight_o = ease * oq / np.maximum(oq + Q[over_b], 1e-12)
        o_point = np.stack([np.interp(foot_b[over_b], arc_o, other.points[:, c]) for c in range(3)], axis=1)
        P[over_b] += weight_o[:, None] * (o_point - P[over_b])
        W[over_b] += weight_o * (np.interp(foot_b[over_b], arc_o, other.width) - W[over_b])
        D[over_b] += weight_o * (np.interp(foot_b[over_b], arc_o, other.depth) - D[over_b])
        Q[over_b] = np.maximum(Q[over_b], oq)
    # the other's points beyond base's ends (foot clamped to an end, and off the line): snapped on by the
    # offset between base's end and the other's nearest point there
    parts_before, parts_after = [], []
    # beyond an end: the foot clamps to it and the point lies past it along the line's direction there
    out_start = base.points[0] - base.points[1]
    out_end = base.points[-1] - base.points[-2]
    before = (foot <= 1e-9) & ((other.points - base.points[0]) @ out_start > 0)
    after = (foot >= arc_b[-1] - 1e-9) & ((other.points - base.points[-1]) @ out_end > 0)
    for sel, end, parts in ((before, 0, parts_before), (after, -1, parts_after)):
        if not sel.any():
            continue
        j = int(np.argmin(np.linalg.norm(other.points - P[end], axis=1)))
        shift = P[end] - other.points[j]
        idx = np.flatnonzero(sel)
        # keep the overhang's own order, running away from base's end
        idx = idx[np.argsort(np.linalg.norm(other.points[idx] - other.points[j], axis=1))]
        parts.append((other.points[idx] + shift, other.width[idx], other.depth[idx], other.quality[idx]))
    pieces = [(p[::-1], w[::-1], d[::-1], q[::-1]) for p, w, d, q in parts_before] + [(P, W, D, Q)] + parts_after
    return SurfaceWrinkle(_merged_identity(base.wrinkle, other.wrinkle), base.color,
                          np.concatenate([p[0] for p in pieces]), np.concatenate([p[1] for p in pieces]),
                          np.concatenate([p[2] for p in pieces]), np.concatenate([p[3] for p in pieces]))


def merge_camera_wrinkles(views: Sequence[Sequence[SurfaceWrinkle]], *, snap_mm: float = SNAP_MM
                          ) -> list[SurfaceWrinkle]:
    """Merge the wrinkles several cameras saw at one frame into one set.

    Parameters
    ----------
    views : sequence (per camera) of sequences of SurfaceWrinkle
    snap_mm : float, default :data:`SNAP_MM`
        Two curves of the same paint are one wrinkle when at least a third of the shorter one lies
        within this distance of the other.

    Returns
    -------
    list of SurfaceWrinkle
        Each wrinkle once: a curve only one camera saw as it is; one several saw, the one seen most
        squarely (largest summed ``quality`` along it) with the others snapped onto it and blended
        linearly by ``quality`` where they overlap, their overhangs appended.
    """
    merged: list[SurfaceWrinkle] = []
    for view in views:
        for curve in view:
            best, best_share = -1, 0.0
            for j, have in enumerate(merged):
                if have.color != curve.color or _cameras_of(curve.wrinkle) & _cameras_of(have.wrinkle):
                    continue
                d_new, _ = nearest_on_polyline(curve.points, have.points)
                d_have, _ = nearest_on_polyline(have.points, curve.points)
                share = max(float(np.mean(d_new < snap_mm)), float(np.mean(d_have < snap_mm)))
                if share > best_share:
                    best, best_share = j, share
            if best < 0 or best_share < 1.0 / 3.0:
                merged.append(curve)
                continue
            have = merged[best]
            if curve.quality.sum() > have.quality.sum():
                merged[best] = _blend_pair(curve, have, snap_mm)
            else:
                merged[best] = _blend_pair(have, curve, snap_mm)
    return merged

