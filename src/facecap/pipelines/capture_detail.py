"""``facecap detail``'s job: fine detail from footage by space-time shape from shading (Lo et al.), on a result.

The layer below (``animate``, ``blend``, ``solve-muscles`` or ``wrinkles``) is
read with its correspondence map; the footage's first frame chooses the region
(:func:`~facecap.sfs.select_detail_region`) and the reflectance
(:func:`~facecap.sfs.estimate_reflectance`); every window of video frames runs on
the frame runner as a :class:`~facecap.sfs.DetailFrameStage`; the heights are
interpolated to the take's rate, added along the layer's normals, and the
result written as the layer below was, plus ``detail.json``.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ..errors import FacecapWarning, InputError

__all__ = ["DetailCapture", "capture_detail", "write_detail_frame_maps"]

REFLECTANCE_PATCH_MM = 20.0
"""Side of the patches the specular lobe is fitted per (then blended over half of it): the forehead and nose
are oilier than the cheeks, a few centimetres apart."""

CHUNK_VIDEO_FRAMES = 8
"""Video frames per runner task (each also solves 3 frames of halo on each side)."""

DEFAULT_MAP_SIZE = 1024
"""Texels along each side of the detail's maps (``--map-size``)."""


class DetailCapture(NamedTuple):
    """What :func:`capture_detail` wrote.

    Attributes
    ----------
    out_dir : Path
    n_video_frames : int
    region_vertices : int
    timings : dict of str to float
    """

    out_dir: Path
    n_video_frames: int
    region_vertices: int
    timings: dict[str, float]


def _transfer_of(image: np.ndarray, transfer: str, where: str) -> str:
    """'linear' or 'srgb': the option's, or from the pixel type (8-bit: sRGB; 16-bit and float: linear)."""
    if transfer in ("linear", "srgb"):
        return transfer
    if transfer != "auto":
        raise InputError(f"transfer: expected 'auto', 'linear' or 'srgb', got {transfer!r}")
    return "srgb" if np.asarray(image).dtype == np.uint8 else "linear"


def _transfer_doubt(image: np.ndarray, transfer: str, where: str) -> str | None:
    """A warning when an explicit ``transfer`` goes against how files of this pixel type are written, else None.

    Cameras and encoders write 8-bit files sRGB-encoded and 16-bit or float files linear; reading either the
    other way bends every shading value by the sRGB curve (a factor 2-5 in the mid-tones), which the solve
    then reads as slopes. The option may be right (a linear 8-bit machine-vision camera), so this warns.
    """
    if transfer not in ("linear", "srgb"):
        return None
    usual = _transfer_of(image, "auto", where)
    if usual == transfer:
        return None
    kind = "8-bit" if np.asarray(image).dtype == np.uint8 else "16-bit or float"
    return (f"{where}: {kind} footage read as {transfer} (--transfer {transfer}); such files are usually {usual}: "
            f"if these are, every shading value is bent by the sRGB curve")


def capture_detail(result_dir: str | os.PathLike[str], cameras: Sequence[Any], footage: Sequence[Any], lights: Any,
                   out_dir: str | os.PathLike[str], *, video_rate_hz: float | None = None,
                   first_mocap_frame: float = 0.0, regions: Any = None, transfer: str = "auto",
                   per_sample_albedo: bool = True, specular: bool = True, rest_misfit_limit: float | None = None,
                   scheduler: str | None = "synchronous", n_workers: int = 2,
                   work_dir: Any = None, exports: Sequence[str] = (), chunk_frames: int = CHUNK_VIDEO_FRAMES,
                   progress: bool = False, options: Mapping[str, Any] | None = None,
                   export_options: Mapping[str, Any] | None = None, overwrite: bool = False,
                   map_size: int = DEFAULT_MAP_SIZE, bilateral_mm: float | None = None) -> DetailCapture:
    """Add the fine detail the footage shows to a result.

    Parameters
    ----------
    result_dir : str or path-like
        The layer below; it must hold ``correspondence.npz`` (the map into the mocap frame).
    cameras : sequence of facecap.cameras.Camera
        Calibrated in the mocap frame, one per footage.
    footage : sequence of str or path-like
        Image folders or video files, in ``cameras`` order.
    lights : LightSetup or path-like
        The stage's lights (``lights.json``).
    out_dir : str or path-like
    video_rate_hz : float
        The footage's rate (required).
    first_mocap_frame : float, default 0
        The mocap frame of video frame 0.
    regions : (n,) bool array or path-like, optional
        Restrict the detail to these vertices (:func:`facecap.io.read_region_mask`).
    transfer : {'auto', 'linear', 'srgb'}, default 'auto'
        How the footage encodes light; 'auto': 8-bit is sRGB, 16-bit and float are linear.
    per_sample_albedo : bool, default True
        An albedo per sample from the rest frame (freckles, moles and brows are not shading); False: one per
        region as the paper does.
    specular : bool, default True
        Fit and shade Phong's specular lobe; False: Lambertian (the single-frame baseline of the paper's Fig. 9,
        with ``options={'temporal': 0}``, ``per_sample_albedo=False`` and ``rest_misfit_limit=inf``).
    rest_misfit_limit : float, optional
        Samples whose rest frame the fitted reflectance explains worse than this (relative RMS) are left out;
        default :data:`~facecap.sfs.REST_MISFIT_LIMIT`. A Lambertian fit misses every highlight, so the baseline
        keeps everything (``inf``).
    scheduler, n_workers, work_dir, chunk_frames, progress
        The frame runner's (:func:`~facecap.runner.run_frames`).
    exports : sequence of str, default ()
    options : mapping, optional
        :data:`~facecap.sfs.DETAIL_DEFAULTS`' keys.
    export_options : mapping, optional
    overwrite : bool, default False
    map_size : int, default 1024
        Texels along each side of the per-video-frame displacement and normal maps on the scan's UVs
        (``maps/``, :func:`write_detail_frame_maps`); 0: no maps. A scan without UVs gets none either
        (``detail.json`` says why).
    bilateral_mm : float, optional
        The paper's post-filter (4.3): the heights filtered by :class:`~facecap.sfs.BilateralHeights` with this
        spatial standard deviation (``--bilateral``; :data:`~facecap.sfs.DEFAULT_BILATERAL_MM` is 0.3 mm). None:
        none, the default (measured in ``benchmarks/RESULTS.md``, "Fine detail from video").

    Returns
    -------
    DetailCapture

    Raises
    ------
    InputError
        A result without its correspondence map, counts that do not match, footage of another size than its
        calibration or not covering the take, no part of the face both seen and lit, a ``bilateral_mm`` that
        is not a length.
    """
    from ..cameras import LightSetup, open_footage, read_light_file, synchronize
    from ..io.read_region_mask import read_region_mask
    from ..io.read_result import read_result
    from ..io.write_performance import PerformanceWriter, check_result_destination
    from ..mesh.vertex_normals import vertex_normals
    from ..runner import run_frames
    from ..sfs.bilateral_heights import BilateralHeights
    from ..sfs.detail_frame_stage import DetailFrameStage
    from ..sfs.estimate_reflectance import REST_MISFIT_LIMIT, estimate_reflectance, rest_misfit
    from ..sfs.select_detail_region import locality_order, select_detail_region
    from ..sfs.surface_low_pass import SurfaceLowPass
    from ..units import mm_per_unit
    from .finish_result import finish_result

    timings: dict[str, float] = {}
    start_all = time.perf_counter()
    if bilateral_mm is not None and not (np.isfinite(bilateral_mm) and bilateral_mm > 0):
        raise InputError(f"bilateral_mm (--bilateral): expected a length > 0 in mm, got {bilateral_mm!r}")
    check_result_destination(out_dir, overwrite=overwrite)
    result_dir = Path(result_dir)
    result = read_result(result_dir)
    if not (result_dir / "correspondence.npz").is_file():
        raise InputError("the result has no correspondence.npz (the map into the mocap frame, where the cameras "
                         "are calibrated): make it with facecap animate or facecap blend", path=str(result_dir))
    cameras, footage = list(cameras), [str(f) for f in footage]
    if not cameras or len(cameras) != len(footage):
        raise InputError(f"expected one camera per footage: {len(cameras)} cameras, {len(footage)} footage")
    if video_rate_hz is None:
        raise InputError("video_rate_hz: the footage's rate is needed (the camera file's footage.rate_hz)")
    setup = lights if isinstance(lights, LightSetup) else read_light_file(lights)
    counts, first_images = [], []
    for camera, path in zip(cameras, footage):
        with open_footage(path) as clip:
            clip.check_camera(camera)
            counts.append(len(clip))
            first_images.append(clip.frame(0))
    chosen_transfer = {_transfer_of(image, transfer, path) for image, path in zip(first_images, footage)}
    if len(chosen_transfer) != 1:
        raise InputError("the footage mixes 8-bit and 16-bit files: give --transfer")
    encoding = chosen_transfer.pop()
    doubts = {_transfer_doubt(image, transfer, path) for image, path in zip(first_images, footage)} - {None}
    for doubt in sorted(doubts):
        warnings.warn(doubt, FacecapWarning, stacklevel=2)
    n_video = min(counts)
    sync = synchronize(result.rate, result.n_frames, video_rate_hz, n_video, first_mocap_frame=first_mocap_frame,
                       footage_name=" and ".join(footage))
    mocap_frames = sync.mocap_frame(np.arange(n_video))
    mask = None
    if regions is not None:
        mask = read_region_mask(regions, result.n_vertices) if isinstance(regions, (str, os.PathLike)) \
            else np.asarray(regions, dtype=bool)
        if mask.shape != (result.n_vertices,):
            raise InputError(f"regions: expected {result.n_vertices} flags, got shape {mask.shape}")
    t = time.perf_counter()
    everywhere = np.arange(result.n_vertices)
    # the survey needs no camera blur (it models the detail's change, and there is none yet)
    survey = DetailFrameStage(str(result_dir.resolve()), cameras, footage, setup, mocap_frames,
                              everywhere, np.ones(everywhere.size), 0.0, 1.0, encoding,
                              {**dict(options or {}), "blur_px": 0.0})
    rest, found = survey.observe(0, gain=False)
    direct = np.sum(rest.irradiance * np.maximum(np.einsum("rk,lrk->lr", rest.normals, rest.to_light), 0), axis=0)
    region_mask = select_detail_region(rest.weight, direct, result.mesh.faces, mask=mask)
    if not region_mask.any():
        lit_share = float(np.mean(direct > 0))
        why = "no light reaches the face (is a light behind it?)" if lit_share < 0.05 else \
            "no part of the face is seen well by every camera"
        raise InputError(f"nothing to solve: {why}" + (" inside --regions" if mask is not None else ""))
    region = np.flatnonzero(region_mask)
    clipped = float(found["clipped"][:, region].mean())
    if clipped > 0.02:
        warnings.warn(f"{100 * clipped:.1f} % of the observations are clipped highlights (left out): lower the "
                      "exposure or the key light", FacecapWarning, stacklevel=2)

    def restricted(frame: Any) -> Any:
        return frame._replace(normals=frame.normals[region], gradient=None, to_light=frame.to_light[:, region],
                              irradiance=frame.irradiance[:, region], to_eye=frame.to_eye[:, region],
                              intensity=frame.intensity[:, region], weight=frame.weight[:, region])

    # a lobe per patch of about REFLECTANCE_PATCH_MM, blended across the patches' edges
    stage_for_mesh = DetailFrameStage(str(result_dir.resolve()), cameras, footage, setup, mocap_frames,
                                      region, np.ones(region.size), 0.0, 1.0, encoding,
                                      {**dict(options or {}), "blur_px": 0.0})
    rest_positions = result.mesh.vertices[region]
    patches = np.unique(np.floor(rest_positions / REFLECTANCE_PATCH_MM).astype(np.int64), axis=0,
                        return_inverse=True)[1].ravel()
    region_faces, _ = stage_for_mesh.region_mesh()
    blend = SurfaceLowPass(rest_positions, region_faces, REFLECTANCE_PATCH_MM / 2)
    reflectance = estimate_reflectance([restricted(rest)], ambient=setup.ambient, per_sample=per_sample_albedo,
                                       specular=specular, patches=patches if per_sample_albedo else None,
                                       smooth=lambda values: blend(values))
    misfit = rest_misfit([restricted(rest)], reflectance, ambient=setup.ambient)
    limit = REST_MISFIT_LIMIT if rest_misfit_limit is None else float(rest_misfit_limit)
    trusted = np.isfinite(misfit) & (misfit <= limit)
    if not trusted.any():
        raise InputError("the rest frame's shading cannot be explained anywhere in the region (check the lights "
                         "file, the cameras and --transfer)")
    left_out = float(1.0 - trusted.mean())
    if left_out > 0.3:
        warnings.warn(f"{100 * left_out:.0f} % of the region is left out: the cameras disagree there at the rest "
                      "frame by more than the shading model explains (the layer below misplaced, or the lights "
                      "or cameras off)", FacecapWarning, stacklevel=2)
    region = region[trusted]
    reflectance = reflectance._replace(albedo=reflectance.albedo[trusted],
                                       k_s=np.broadcast_to(reflectance.k_s, trusted.shape)[trusted],
                                       alpha=np.broadcast_to(reflectance.alpha, trusted.shape)[trusted])
    # solved in an order that keeps mesh neighbours close in memory (detail_region.npy records it)
    order = locality_order(region, result.mesh.faces)
    region = region[order]
    reflectance = reflectance._replace(albedo=reflectance.albedo[order], k_s=reflectance.k_s[order],
                                       alpha=reflectance.alpha[order])
    timings["region_and_reflectance_s"] = time.perf_counter() - t
    stage = DetailFrameStage(str(result_dir.resolve()), cameras, footage, setup, mocap_frames, region,
                             reflectance.albedo, reflectance.k_s, reflectance.alpha, encoding, options)
    t = time.perf_counter()
    own_work = work_dir is None
    work = Path(tempfile.mkdtemp(prefix="facecap-detail-")) if own_work else Path(work_dir)
    try:
        run = run_frames(stage, n_video, work, chunk_frames=chunk_frames, scheduler=scheduler, n_workers=n_workers,
                         progress=progress)
        timings["shape_from_shading_s"] = time.perf_counter() - t
        heights = run.load("heights")
        if bilateral_mm is not None:  # on the rest surface in mm, as the filter's lengths are
            rest_mm = result.mesh.vertices[region] * float(mm_per_unit(result.units))
            heights = BilateralHeights(rest_mm, bilateral_mm)(heights).astype(np.float32)
        residual, residual_before = run.load("residual"), run.load("residual_before")
        t = time.perf_counter()
        bracket = sync.bracket(np.arange(result.n_frames))
        mm = float(mm_per_unit(result.units))
        faces = result.mesh.faces
        head_pose = result.head_motion.copy() if result.head_motion is not None else None
        if head_pose is not None:
            head_pose[:, :3, 3] *= mm
        with PerformanceWriter(out_dir, mesh=result.mesh, rate=result.rate, n_frames=result.n_frames,
                               exports=exports, export_options=export_options, overwrite=overwrite) as writer:
            def compute(lo: int, hi: int, out: np.ndarray) -> None:
                out[:] = result.frames(lo, hi) * np.float32(mm)
                b, a, w = bracket.before[lo:hi], bracket.after[lo:hi], bracket.weight[lo:hi].astype(np.float32)
                h = (1 - w)[:, None] * heights[b] + w[:, None] * heights[a]
                for k in range(hi - lo):
                    normals = vertex_normals(out[k].astype(np.float64), faces, region)
                    out[k, region] += (h[k][:, None] * normals).astype(np.float32)

            writer.stream(compute, batch_frames=16, head_pose=head_pose, progress=progress, desc="detail")
            for name in ("head_motion.npy", "markers.npy", "correspondence.npz"):
                if (result_dir / name).is_file():
                    shutil.copyfile(result_dir / name, writer.path(name))
            document = {
                "method": "lo-spacetime-shape-from-shading", "units": "mm",
                "reflectance": {"k_s_median": float(np.median(reflectance.k_s)),
                                "k_s_range": [float(np.min(reflectance.k_s)), float(np.max(reflectance.k_s))],
                                "alpha_median": float(np.median(reflectance.alpha)),
                                "alpha_range": [float(np.min(reflectance.alpha)), float(np.max(reflectance.alpha))],
                                "lobe": "per patch of %g mm, blended" % REFLECTANCE_PATCH_MM
                                        if np.ndim(reflectance.k_s) else "one",
                                "albedo": "per sample (rest frame)" if per_sample_albedo else "uniform",
                                "specular": bool(specular),
                                "albedo_median": float(np.median(reflectance.albedo)),
                                "rest_residual": reflectance.residual},
                "transfer": encoding, "region_vertices": int(region.size), "clipped_share": clipped,
                "left_out_by_rest_misfit": left_out, "rest_misfit_limit": limit,
                "options": stage.options,
                "bilateral_mm": None if bilateral_mm is None else float(bilateral_mm),
                "frames": [{"video_frame": j, "mocap_frame": float(mocap_frames[j]),
                            "residual": float(residual[j]), "residual_base": float(residual_before[j]),
                            "height_rms_mm": float(np.sqrt(np.mean(heights[j] ** 2)))} for j in range(n_video)],
            }
            # -- the detail's maps on the scan's UVs (maps/) ------------------------------------------------
            t_maps = time.perf_counter()
            document["maps"] = write_detail_frame_maps(writer.path("maps"), result.mesh, heights, region,
                                                       stage.large_scale, mocap_frames, map_size=map_size)
            timings["maps_s"] = time.perf_counter() - t_maps
            writer.path("detail.json").write_text(json.dumps(document, indent=1))
            np.save(writer.path("detail_region.npy"), region)
            timings["write_s"] = time.perf_counter() - t
            timings["total_s"] = time.perf_counter() - start_all
            final = finish_result(writer, {"method": "lo-spacetime-shape-from-shading",
                                           "large_scale": writer.record_path(result_dir),
                                           "footage": [writer.record_path(f) for f in footage],
                                           "cameras": [c.name for c in cameras],
                                           "video_rate_hz": float(video_rate_hz),
                                           "first_mocap_frame": float(first_mocap_frame),
                                           "markers": list(result.marker_labels) if result.markers is not None else [],
                                           "timings": timings})
    finally:
        if own_work:
            shutil.rmtree(work, ignore_errors=True)
    return DetailCapture(Path(final), n_video, int(region.size), timings)


def write_detail_frame_maps(folder: str | os.PathLike[str], mesh: Any, heights: np.ndarray, region: np.ndarray,
                            base_at: Any, mocap_frames: np.ndarray, *, map_size: int = DEFAULT_MAP_SIZE,
                            padding: int = 4) -> dict[str, Any]:
    """Write every video frame's displacement and normal maps on the scan's UVs; what ``detail.json`` records.

    Parameters
    ----------
    folder : path-like
        The maps folder (created).
    mesh : facecap.structures.Mesh
        The scan (its UVs; its triangles are the base surface's).
    heights : (V, r) float32 array, mm
    region : (r,) int array
    base_at : callable
        ``base_at(j)``: the base surface (n, 3) mm at video frame ``j``.
    mocap_frames : (V,) float array
    map_size : int, default 1024
        0: no maps.
    padding : int, default 4

    Returns
    -------
    dict
        ``{'folder': 'maps', 'size': ..., 'setup_s': ..., 'ms_per_frame': ...}``, or ``{'none': why}``.
    """
    from ..io.write_detail_maps import MAPS_FOLDER, write_detail_maps, write_maps_index
    from ..io.write_gltf import triangle_corners
    from ..sfs.detail_maps import DetailMaps

    if int(map_size) != map_size or map_size < 0:
        raise InputError(f"map_size: expected a whole number of texels >= 0, got {map_size!r}")
    if map_size == 0:
        return {"none": "map_size is 0 (--map-size 0)"}
    if mesh.uvs is None:
        return {"none": "the scan has no UVs (texture coordinates), so there is no atlas to hold the maps"}
    if mesh.uv_indices is None:
        uv_triangles = mesh.faces  # one UV per vertex
    else:
        uv_triangles = np.asarray(mesh.uv_indices, dtype=np.int64)[triangle_corners(mesh)]
    t = time.perf_counter()
    maps = DetailMaps(mesh.uvs, uv_triangles, mesh.faces, region, int(map_size), padding=padding)
    setup_s = time.perf_counter() - t
    folder = Path(folder)
    folder.mkdir(exist_ok=True)
    t = time.perf_counter()
    for j in range(heights.shape[0]):
        write_detail_maps(folder, j, maps.displacement(heights[j]), maps.normal_map(base_at(j), heights[j]),
                          mocap_frame=float(mocap_frames[j]))
    per_frame = (time.perf_counter() - t) / max(heights.shape[0], 1)
    write_maps_index(folder, size=int(map_size), video_frames=list(range(heights.shape[0])),
                     mocap_frames=[float(m) for m in mocap_frames], padding=padding)
    return {"folder": MAPS_FOLDER, "size": int(map_size), "setup_s": setup_s, "ms_per_frame": 1000 * per_frame}
