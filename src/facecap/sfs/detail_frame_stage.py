"""One window of video frames of the detail layer, as a frame-runner stage (Lo et al. 3.2, 4.2).

:class:`DetailFrameStage` is what ``facecap detail`` (:func:`facecap.pipelines.capture_detail`)
runs on every chunk of video frames. For each frame of the chunk and of its halo
(:data:`~facecap.sfs.solve_heights.TEMPORAL_REACH` frames each side, so that the
temporal term sees the same neighbours inside a chunk as across chunks):

1. the layer below at the frame's mocap time, carried into the mocap frame where
   the cameras and lights are calibrated (the result's correspondence map, as the
   wrinkle layer does), its normals, a ray caster;
2. each camera's image read at the region's samples (:func:`~facecap.sfs.sample_footage`),
   the lights' directions, falloff and cast shadows at them;
3. observations removed where they cannot be trusted: on and around the markers
   (painted dots, not skin), along the edge of a cast shadow (the layer below
   puts it a little off), clipped highlights;
4. the slow gain taken out (:class:`~facecap.sfs.SurfaceLowPass`);

then the whole window is solved at once (:func:`~facecap.sfs.solve_heights`) and
the chunk's frames kept.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..typing import FloatArray
from .camera_blur import DEFAULT_BLUR_PX, camera_blur
from .sample_footage import sample_footage
from .solve_heights import TEMPORAL_REACH, HeightWeights, ShadedFrame, shade_frame, solve_heights
from .surface_low_pass import SurfaceLowPass
from .vertex_gradient import vertex_gradient

__all__ = ["DetailFrameStage", "DETAIL_DEFAULTS"]

DETAIL_DEFAULTS: dict[str, Any] = {
    "spatial": HeightWeights().spatial,
    "temporal": HeightWeights().temporal,
    "anchor": HeightWeights().anchor,
    "sparsity_mm": HeightWeights().sparsity_mm,
    "bulge": HeightWeights().bulge,
    "iterations": 3,
    "gain_sigma_mm": 4.0,
    # observations left out around each marker: a painted dot or sphere up to 4 mm across with 1.5 mm to spare;
    # 5 mm left out 10-13 % of the generator's line vertices (paint 2.5 mm); 3.5 mm: tuned0 0.839 -> 0.829,
    # held2 0.819 -> 0.789 vertex by vertex, on marks 0.0045 -> 0.0053 mm (benchmarks/RESULTS.md)
    "marker_patch_mm": 3.5,
    "shadow_edge_rings": 2,
    "blur_px": DEFAULT_BLUR_PX,
    "follow_skin": True,
}
"""The stage's options and their defaults (``detail.json`` records the values used)."""


class DetailFrameStage:
    """The per-window work of the detail layer (picklable, deterministic).

    Parameters
    ----------
    result_dir : str
        The layer below (an ``animate``, ``blend``, ``solve-muscles`` or ``wrinkles`` result).
    cameras : sequence of Camera
    footage : sequence of str
        One footage per camera.
    lights : LightSetup
        The stage's lights (``lights.json``).
    mocap_frames : (V,) float array
        The mocap frame of each video frame.
    region : (r,) int array
        The scan's vertices the detail is solved at.
    albedo : (r,) float array
    k_s, alpha : float or (r,) float arrays
    transfer : {'linear', 'srgb'}
        How the footage encodes light.
    options : mapping, optional
        :data:`DETAIL_DEFAULTS`' keys.
    """

    def __init__(self, result_dir: str, cameras: Sequence[Any], footage: Sequence[str], lights: Any,
                 mocap_frames: Any, region: Any, albedo: Any, k_s: Any, alpha: Any, transfer: str,
                 options: Mapping[str, Any] | None = None) -> None:
        self.result_dir = str(result_dir)
        self.cameras = list(cameras)
        self.footage = [str(p) for p in footage]
        self.lights = lights
        self.mocap_frames = np.asarray(mocap_frames, dtype=np.float64)
        self.region = np.asarray(region, dtype=np.int64)
        self.albedo = np.asarray(albedo, dtype=np.float64)
        # one lobe, or one per sample (per patch, blended)
        self.k_s = np.broadcast_to(np.asarray(k_s, dtype=np.float64), self.region.shape).copy()
        self.alpha = np.broadcast_to(np.asarray(alpha, dtype=np.float64), self.region.shape).copy()
        if transfer not in ("linear", "srgb"):
            raise InputError(f"transfer: expected 'linear' or 'srgb', got {transfer!r}")
        self.transfer = transfer
        unknown = set(options or {}) - set(DETAIL_DEFAULTS)
        if unknown:
            raise InputError(f"options: unknown {sorted(unknown)} (known: {sorted(DETAIL_DEFAULTS)})")
        self.options = {**DETAIL_DEFAULTS, **dict(options or {})}

    def __getstate__(self) -> dict[str, Any]:
        return {k: v for k, v in self.__dict__.items() if not k.startswith("_")}

    # -- per-process caches ------------------------------------------------------------------------------
    def _result(self) -> tuple[Any, dict[str, np.ndarray]]:
        opened = getattr(self, "_opened", None)
        if opened is None:
            from ..io.mocap_correspondence import read_mocap_correspondence
            from ..io.read_result import read_result

            correspondence = read_mocap_correspondence(Path(self.result_dir) / "correspondence.npz")
            opened = self._opened = (read_result(self.result_dir), correspondence)
        return opened

    def image(self, camera_index: int, video_frame: int) -> np.ndarray:
        """A footage frame as linear light in [0, 1] (float32)."""
        from ..cameras import image_to_float, open_footage, srgb_to_linear

        clips = self.__dict__.setdefault("_clips", {})
        if camera_index not in clips:
            clips[camera_index] = open_footage(self.footage[camera_index])
        image = image_to_float(clips[camera_index].frame(video_frame))
        return srgb_to_linear(np.clip(image, 0.0, 1.0)) if self.transfer == "srgb" else image

    def region_mesh(self) -> tuple[np.ndarray, sp.csr_matrix]:
        """The triangles inside the region (reindexed) and the region's one-ring adjacency."""
        cached = getattr(self, "_region_faces", None)
        if cached is None:
            result = self._result()[0]
            F = result.mesh.faces
            index = np.full(result.n_vertices, -1, dtype=np.int64)
            index[self.region] = np.arange(self.region.size)
            inside = np.all(index[F] >= 0, axis=1)
            faces = index[F[inside]]
            r = self.region.size
            i = np.concatenate([faces[:, 0], faces[:, 1], faces[:, 2]])
            j = np.concatenate([faces[:, 1], faces[:, 2], faces[:, 0]])
            adjacency = sp.csr_matrix((np.ones(2 * i.size), (np.r_[i, j], np.r_[j, i])), shape=(r, r))
            adjacency.data[:] = 1.0
            cached = self._region_faces = (faces, adjacency)
        return cached

    def _area(self) -> np.ndarray:
        """The region's Voronoi areas on the scan (mm^2): what each sample stands for in the camera's blur."""
        area = getattr(self, "_areas", None)
        if area is None:
            from ..mesh.laplacian import laplace_operators

            result = self._result()[0]
            area = self._areas = laplace_operators(result.mesh.vertices, result.mesh.faces).mass[self.region]
        return area

    def _low_pass(self) -> SurfaceLowPass:
        low = getattr(self, "_low", None)
        if low is None:
            result = self._result()[0]
            faces, _ = self.region_mesh()
            low = self._low = SurfaceLowPass(result.mesh.vertices[self.region], faces, self.options["gain_sigma_mm"])
        return low

    def _rest_view(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per camera: the rest frame's (video frame 0) luminance and where the samples were read in it."""
        rest = getattr(self, "_rest", None)
        if rest is None:
            from .sample_footage import luminance

            _, X = self.mocap_vertices(0)
            rest = self._rest = [(luminance(self.image(c, 0)), camera.project(X[self.region]).pixels)
                                 for c, camera in enumerate(self.cameras)]
        return rest

    def _followed_pixels(self, images: Sequence[np.ndarray], points: FloatArray) -> tuple[list[np.ndarray], np.ndarray]:
        """Per camera where each sample's rest-frame skin point is now (:func:`~facecap.sfs.follow_skin`)."""
        from .follow_skin import follow_skin
        from .sample_footage import luminance

        pixels, followed = [], []
        for c, (camera, (rest_grey, rest_pixels)) in enumerate(zip(self.cameras, self._rest_view())):
            at, ok = follow_skin(rest_grey, luminance(images[c]), rest_pixels, camera.project(points).pixels)
            pixels.append(at)
            followed.append(ok)
        return pixels, np.stack(followed)

    # -- one frame ---------------------------------------------------------------------------------------
    def large_scale(self, video_frame: int) -> FloatArray:
        """The layer below (face frame, mm) at a video frame's mocap time (linear between mocap frames)."""
        from ..wrinkles.wrinkle_frame_stage import result_frame_at

        return result_frame_at(self._result()[0], float(self.mocap_frames[video_frame]))

    def mocap_vertices(self, video_frame: int) -> tuple[FloatArray, FloatArray]:
        """The layer below at a video frame: in the face's frame and carried into the mocap frame (mm)."""
        from ..wrinkles.wrinkle_frame_stage import large_scale_in_mocap

        result, correspondence = self._result()
        at = float(np.clip(self.mocap_frames[video_frame], 0, result.n_frames - 1))
        A = self.large_scale(video_frame)
        return A, large_scale_in_mocap(A, correspondence, at)

    def observe(self, video_frame: int, *, gain: bool = True,
                gradient: Any = None) -> tuple[ShadedFrame, dict[str, Any]]:
        """One frame of the region as the cameras and lights see the layer below.

        Returns the frame (its ``gradient`` the one given, or this frame's) and what was found on the way:
        ``world`` (r, 3) the samples in the mocap frame, ``clipped`` (C, r), ``seen`` (C, r) before the
        removals, ``gain`` (r,) the slow gain taken out (1 without ``gain``), ``followed`` (C, r) where the
        optical flow placed the sample (None on the rest frame or without ``follow_skin``).
        """
        from ..cameras import RayCaster
        from ..mesh.vertex_normals import vertex_normals

        result = self._result()[0]
        F = result.mesh.faces
        at = float(np.clip(self.mocap_frames[video_frame], 0, result.n_frames - 1))
        A, X = self.mocap_vertices(video_frame)
        caster = RayCaster(X, F)
        region = self.region
        N = vertex_normals(X, F, region)
        P = X[region]
        visible = [caster.visible(P, camera) for camera in self.cameras]
        images = [self.image(c, video_frame) for c in range(len(self.cameras))]
        pixels, followed = None, None
        if self.options["follow_skin"] and video_frame != 0:
            pixels, followed = self._followed_pixels(images, P)
        samples = sample_footage(images, self.cameras, P, N, visible, pixels=pixels)
        weight = samples.weight.copy()
        setup = self.lights
        to_light, irradiance, lit_all = [], [], []
        for light in setup.lights:
            direction, E = light.arriving(P)
            lit = caster.lit(P, light, normals=N)
            to_light.append(direction)
            irradiance.append(E * lit)
            lit_all.append(lit)
        _, adjacency = self.region_mesh()
        edge = np.zeros(region.size, dtype=bool)
        for lit in lit_all:  # samples whose one-ring holds both lit and shadowed samples, grown by rings
            lit_f = lit.astype(np.float64)
            band = ((adjacency @ lit_f) > 0) & ((adjacency @ (1.0 - lit_f)) > 0)
            for _ in range(int(self.options["shadow_edge_rings"]) - 1):
                band = band | ((adjacency @ band.astype(np.float64)) > 0)
            edge |= band
        weight[:, edge] = 0.0
        if result.markers is not None and self.options["marker_patch_mm"] > 0:
            from scipy.spatial import cKDTree
            from ..units import mm_per_unit

            frame = int(round(at))
            markers = np.asarray(result.markers[frame], dtype=np.float64) * float(mm_per_unit(result.units))
            markers = markers[np.all(np.isfinite(markers), axis=1)]
            if markers.size:
                near = cKDTree(markers).query(A[region], distance_upper_bound=self.options["marker_patch_mm"])[0]
                weight[:, np.isfinite(near)] = 0.0
        if gradient is None:
            gradient = vertex_gradient(X, F, rows=region, columns=region)
        blur = None
        if self.options["blur_px"] > 0:
            blur = []
            area = self._area()
            for c in range(len(self.cameras)):
                rows = np.flatnonzero(samples.weight[c] > 0)
                inner = camera_blur(samples.pixels[c, rows], area[rows], self.options["blur_px"])
                blur.append(_in_region(inner, rows, region.size))
        frame = ShadedFrame(N, gradient, np.stack(to_light), np.stack(irradiance), samples.to_eye,
                            samples.intensity, weight, blur)
        slow = np.ones(region.size)
        if gain:
            predicted, _, _ = shade_frame(frame, np.zeros(region.size), self.albedo, self.k_s, self.alpha,
                                          setup.ambient)
            ok = (weight > 0) & (predicted > 1e-9)
            ratio = np.where(ok, samples.intensity / np.where(ok, predicted, 1.0), 0.0)
            w = np.where(ok, weight, 0.0)
            total = w.sum(axis=0)
            mean_ratio = np.where(total > 0, (w * ratio).sum(axis=0) / np.maximum(total, 1e-300), 1.0)
            slow = self._low_pass()(mean_ratio, total)
            slow = np.where(np.isfinite(slow) & (slow > 1e-6), slow, 1.0)
            frame = frame._replace(intensity=samples.intensity / slow[None])
        found = {"world": P, "clipped": samples.clipped, "seen": samples.weight > 0, "gain": slow,
                 "followed": followed}
        return frame, found

    def parameters(self) -> dict[str, Any]:
        """What the frames depend on (the runner refuses to resume a run with other values)."""
        return {"result_dir": self.result_dir, "cameras": [c.name for c in self.cameras], "footage": self.footage,
                "lights": self.lights.describe(), "mocap_frames": self.mocap_frames.tolist(),
                "region": [int(self.region.size), int(self.region.sum())],
                "albedo": float(np.round(self.albedo.sum(), 6)), "k_s": float(np.round(self.k_s.sum(), 6)),
                "alpha": float(np.round(self.alpha.sum(), 6)),
                "transfer": self.transfer, "options": self.options}

    def __call__(self, start: int, stop: int, state: Any) -> tuple[dict[str, np.ndarray], None]:
        n_video = self.mocap_frames.size
        first, last = max(start - TEMPORAL_REACH, 0), min(stop + TEMPORAL_REACH, n_video)
        # one gradient operator per window, of its middle frame: the skin's metric changes little in half a second
        _, X = self.mocap_vertices((first + last - 1) // 2)
        gradient = vertex_gradient(X, self._result()[0].mesh.faces, rows=self.region, columns=self.region)
        frames = [self.observe(j, gradient=gradient)[0] for j in range(first, last)]
        o = self.options
        weights = HeightWeights(o["spatial"], o["temporal"], o["anchor"], o["sparsity_mm"], o["bulge"])
        solve = solve_heights(frames, albedo=self.albedo, k_s=self.k_s, alpha=self.alpha,
                              ambient=self.lights.ambient, weights=weights, iterations=o["iterations"])
        keep = slice(start - first, stop - first)
        return {"heights": solve.heights[keep].astype(np.float32),
                "residual": solve.residual[keep].astype(np.float32),
                "residual_before": solve.residual_before[keep].astype(np.float32)}, None


def _in_region(inner: sp.csr_matrix, rows: np.ndarray, size: int) -> sp.csr_matrix:
    """A matrix over the ``rows`` of a region, in the region's numbering; the other samples see themselves.

    Written straight into CSR (``rows`` ascending): a COO conversion sorts 5 million entries a camera.
    """
    counts = np.ones(size, dtype=np.int64)
    counts[rows] = np.diff(inner.indptr)
    indptr = np.zeros(size + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    data = np.ones(indptr[-1])
    indices = np.arange(size, dtype=np.int64)[np.repeat(np.arange(size), counts)]
    row_of_entry = np.repeat(np.arange(rows.size), np.diff(inner.indptr))
    at = indptr[rows][row_of_entry] + (np.arange(inner.nnz) - inner.indptr[row_of_entry])
    data[at] = inner.data
    indices[at] = rows[inner.indices]
    return sp.csr_matrix((data, indices, indptr), shape=(size, size))
