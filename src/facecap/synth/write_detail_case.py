"""A capture case for the detail layer: a take, a scan fine where its lines are, lit footage with markers, the truth.

Space-time shape from shading (Lo et al.; issue 30) reads fine detail from the shading of video under
calibrated lights. This case is its ground truth: fine expression lines and the skin's static bumps on a scan
refined where the lines are, filmed at 25 fps by the two :func:`~facecap.synth.write_footage_case.stage_cameras`
under a spotlight key, a fill and a little ambient (``lights.json``), with view-dependent specular, cast
shadows, an albedo with freckles, moles, brows and an expression-driven flush, and the markers drawn.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..io.atomic_write import atomic_path, atomic_write_text
from ..io.ict_sample import IctSample, load_ict_sample
from ..mesh.vertex_normals import vertex_normals
from ..typing import FloatArray
from .draw_markers import draw_markers
from .fine_lines import FINE_LINE_PROFILES, place_fine_lines, skin_texture_heights
from .generate_performance import SyntheticCase, generate_performance
from .render_footage import SENSOR_DEFAULTS, FootageRenderer, ambient_occlusion, quantize, sensor_noise
from .shade_skin import APPEARANCES, REGION_REFLECTANCE, region_reflectance, shade_skin, skin_radiance, subsurface_blur
from .skin_albedo import SkinRegions, skin_albedo_layers
from .skin_flush import skin_flush
from .studio_lights import studio_lights
from .wrinkle_scan import carry_labels, refine_near, subdivide_scan
from .wrinkles import add_wrinkles, wrinkle_expression_curves, wrinkle_heights
from .write_footage_case import IMAGE_SIZE, MOCAP_RATE_HZ, stage_cameras, write_take_files

__all__ = ["DetailFiles", "write_detail_case", "DETAIL_EDGE_MM", "DETAIL_VIDEO_EVERY", "MARKER_RADIUS_MM", "MARKER_ALBEDO"]

DETAIL_EDGE_MM = 0.3
"""Longest edge of the scan where the fine lines are (mm): a 0.3 mm wide line is one edge across."""
DETAIL_VIDEO_EVERY = 2
"""Mocap frames per video frame: 25 fps video from the 50 Hz take."""
MARKER_RADIUS_MM = 1.5
"""Radius of a drawn marker (a sphere centred on the take's marker, 1.5 mm above the skin: seen as a disc)."""
MARKER_ALBEDO = 0.85
"""The markers' white paint: their radiance is this times the diffuse irradiance at their vertex."""
_MARKER_MARGIN_MM = 1.0  # the markers' skin patches in the truth reach this far beyond the disc


class DetailFiles(NamedTuple):
    """Paths of a written detail case."""

    scan: Path
    markers: Path
    map: Path
    truth: Path
    cameras: Path
    calibrations: tuple[Path, ...]
    videos: tuple[Path, ...]
    lights: Path
    footage: Path


def _one_ring(mask: np.ndarray, faces: np.ndarray) -> np.ndarray:
    out = mask.copy()
    out[np.unique(faces[np.any(mask[faces], axis=1)])] = True
    return out


def _carried(S: sp.csr_matrix, frames: np.ndarray) -> np.ndarray:
    """(T, n_fine, 3) float32: every frame of the take carried to the fine mesh, 16 frames at a time."""
    out = np.empty((frames.shape[0], S.shape[0], 3), dtype=np.float32)
    for t0 in range(0, frames.shape[0], 16):
        block = np.asarray(frames[t0 : t0 + 16], dtype=np.float64)
        flat = S @ np.moveaxis(block, 0, 1).reshape(block.shape[1], -1)
        out[t0 : t0 + 16] = np.moveaxis(flat.reshape(S.shape[0], block.shape[0], 3), 1, 0)
    return out


def _check(name: str, value: Any, ok: bool, expected: str) -> None:
    if not ok:
        raise InputError(f"{name}: expected {expected}, got {value!r}")


def write_detail_case(
    folder: str | Path,
    *,
    n_frames: int = 100,
    seed: int = 0,
    identity: Any = None,
    curves: Any = None,
    levels: int = 2,
    detail_edge_mm: float | None = DETAIL_EDGE_MM,
    appearance: str = "phong",
    lighting: Any = None,
    video_every: int = DETAIL_VIDEO_EVERY,
    first_mocap_frame: int = 0,
    image_size: tuple[int, int] = IMAGE_SIZE,
    ao_rays: int = 16,
    bits: int = 8,
    n_markers: int | None = None,
    markers_drawn: bool = True,
    cameras: Any = None,
    case: SyntheticCase | None = None,
    sample: IctSample | None = None,
    progress: bool = False,
) -> DetailFiles:
    """Generate a take with fine detail and film it under calibrated lights, with the whole truth.

    The large scale is :func:`~facecap.synth.generate_performance.generate_performance` at 50 Hz on
    the ICT face, carried to the scan subdivided ``levels`` times and refined where the fine lines
    are (:func:`~facecap.synth.fine_lines.place_fine_lines`; red-green
    :func:`~facecap.synth.wrinkle_scan.refine_near` to ``detail_edge_mm``), UVs kept. On it: the skin's
    static bumps (:func:`~facecap.synth.fine_lines.skin_texture_heights`, in the scan itself) along each
    frame's normals, then the fine lines' heights along the normals of that
    (:func:`~facecap.synth.wrinkles.add_wrinkles`). Two cameras (:func:`stage_cameras`) film every
    ``video_every``-th mocap frame under ``lighting``, each with its own radiance (the specular
    follows the eye), with cast shadows (:meth:`~facecap.cameras.RayCaster.lit`, per frame), ambient
    occlusion, the markers drawn where visible, shot and read noise.

    Parameters
    ----------
    folder : str or Path
        Created if needed.
    n_frames : int, default 100
        Mocap frames (50 Hz).
    seed : int, default 0
        The take, lines, skin, flush and sensor noise all follow from it.
    identity, n_markers
        Passed to :func:`~facecap.synth.generate_performance.generate_performance`.
    curves : None or as :func:`~facecap.synth.write_footage_case.write_footage_case`
        Default: :func:`~facecap.synth.wrinkles.wrinkle_expression_curves` (brow raise, frown, smile, squint).
    levels : int, default 2
        Subdivisions of the scan before the refinement (2: 148,402 vertices).
    detail_edge_mm : float or None, default 0.3
        Longest edge near the lines (None: no refinement; the lines then sample coarsely).
    appearance : {'phong', 'independent'}, default 'phong'
        ``'phong'``: Phong reflectance by region, the Ricker-like line profile, the ``'phong'`` studio
        lights. ``'independent'``: a GGX specular with Fresnel and a wrapped, blurred diffuse
        (:mod:`~facecap.synth.shade_skin`), double-crease lines
        (:func:`~facecap.synth.fine_lines.double_crease_profile`), other light placements: a footage the
        solver's model did not make, to measure it on.
    lighting : LightSetup, optional
        Lights in the mocap frame instead of :func:`~facecap.synth.studio_lights.studio_lights`.
    video_every : int, default 2
        Mocap frames per video frame (2: 25 fps).
    first_mocap_frame : int, default 0
        The mocap frame of video frame 0 (``0 .. video_every - 1``).
    image_size : (int, int), default (1384, 1038)
    ao_rays : int, default 16
        Ambient-occlusion rays per vertex (the ambient term is small: 16 rays' 0.034 RMS error in ``A``
        is under 0.002 of radiance).
    bits : {8, 16}, default 8
        8-bit PNGs are sRGB-encoded and 16-bit PNGs linear, as cameras write them (``footage.json``'s
        ``response`` says which); ``facecap detail --transfer auto`` reads them so.
    markers_drawn : bool, default True
        Draw the markers (white discs of :data:`MARKER_RADIUS_MM` at the noiseless marker positions).
    cameras : sequence of Camera, optional
    case : SyntheticCase, optional
        A 50 Hz take to use instead of generating one.
    sample : IctSample, optional
    progress : bool, default False

    Returns
    -------
    DetailFiles

    Raises
    ------
    InputError
        On a bad option or a ``case`` not at 50 Hz.

    Notes
    -----
    Written atomically, ``truth.npz`` last: ``scan.obj`` (the rest face with its static bumps, UVs),
    ``take.c3d``, ``map.json``, ``cameras.json``, ``calibration_<cam>.yml``, ``lights.json``,
    ``<cam>/frame_000000.png ...`` (linear, no gamma), ``footage.json`` and ``truth.npz`` (see
    ``docs/synthetic_data.md``, "Footage for the detail layer", for every key).
    """
    from ..cameras import RayCaster, write_image_sequence, write_light_file

    _check("bits", bits, bits in (8, 16), "8 or 16")
    from ..cameras import linear_to_srgb

    def encode(image: FloatArray) -> FloatArray:
        return linear_to_srgb(image) if bits == 8 else image

    _check("appearance", appearance, appearance in APPEARANCES, f"one of {list(APPEARANCES)}")
    _check("video_every", video_every, isinstance(video_every, (int, np.integer)) and not isinstance(video_every, bool)
           and video_every >= 1, "an integer >= 1")
    _check("first_mocap_frame", first_mocap_frame, isinstance(first_mocap_frame, (int, np.integer))
           and 0 <= first_mocap_frame < video_every, f"an integer in 0..{video_every - 1}")
    _check("ao_rays", ao_rays, isinstance(ao_rays, (int, np.integer)) and not isinstance(ao_rays, bool)
           and ao_rays >= 1, "an integer >= 1")
    _check("detail_edge_mm", detail_edge_mm, detail_edge_mm is None or (isinstance(detail_edge_mm, (int, float))
           and not isinstance(detail_edge_mm, bool) and 0.05 <= detail_edge_mm < np.inf), "None or a length >= 0.05 mm")
    try:
        width, height = (int(x) for x in image_size)
    except (TypeError, ValueError):
        raise InputError(f"image_size: expected (width, height) in pixels, got {image_size!r}") from None
    _check("image_size", image_size, width >= 16 and height >= 16, "two integers >= 16")
    sample = load_ict_sample() if sample is None else sample
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    if case is None:
        if curves is None:
            curves = wrinkle_expression_curves(n_frames, sample.expression_names, rate=MOCAP_RATE_HZ, seed=seed)
        case = generate_performance(n_frames=n_frames, rate=MOCAP_RATE_HZ, identity=identity, curves=curves,
                                    n_markers=n_markers, seed=seed, sample=sample)
    elif abs(case.markers.rate - MOCAP_RATE_HZ) > 1e-9:
        raise InputError(f"case: rate {case.markers.rate} Hz; the footage needs a {MOCAP_RATE_HZ:g} Hz take")
    T = case.truth_vertices.shape[0]
    video_frames = np.arange(first_mocap_frame, T, video_every)

    # the scan: subdivided, refined around the lines (placed again on the refined surface: the same lines)
    fine = subdivide_scan(case.scan, levels=levels)
    S = fine.upsample
    mesh = fine.mesh
    if detail_edge_mm is not None:
        lines = place_fine_lines(mesh, sample, seed=seed)
        near, _, _ = wrinkle_heights(lines, mesh.vertices, np.zeros((1, lines.n_curves)))
        refined = refine_near(mesh, _one_ring(near, mesh.faces), max_edge_mm=float(detail_edge_mm))
        S, mesh = (refined.upsample @ S).tocsr(), refined.mesh
    lines = place_fine_lines(mesh, sample, seed=seed)
    F, rest = mesh.faces, mesh.vertices

    # the truth: the take, the static bumps along each frame's normals, the lines along the normals of that
    texture = skin_texture_heights(rest, seed=seed)
    L = _carried(S, case.truth_vertices)
    for t0 in range(0, T, 16):
        block = L[t0 : t0 + 16].astype(np.float64)
        L[t0 : t0 + 16] = block + texture[None, :, None] * vertex_normals(block, F)
    detailed = add_wrinkles(L, F, lines, case.weights, rest=rest, profile=FINE_LINE_PROFILES[appearance])
    G = detailed.vertices
    scan = mesh.with_vertices(rest + texture[:, None] * vertex_normals(rest, F))

    # the skin: albedo with its marks, the flush, reflectance by region
    labels = carry_labels(S, sample.region_labels)
    lm = sample.landmarks
    layers = skin_albedo_layers(rest, seed=seed, region=SkinRegions(labels, sample.region_names, rest[lm[48:60]]),
                                moles=True)
    flush = skin_flush(rest, rest[lm], case.weights, sample.expression_names, rate=MOCAP_RATE_HZ)
    reflectance = region_reflectance(labels, sample.region_names, appearance=appearance)
    if cameras is None:
        cameras = stage_cameras(rest, lm, case.mocap_from_scan, image_size=(width, height))
    cameras = list(cameras)
    lights = studio_lights(rest, lm, case.mocap_from_scan, style=appearance) if lighting is None else lighting
    eyes = np.stack([cam.centre for cam in cameras])
    M = case.n_face_markers

    def world(t: int, V: FloatArray) -> FloatArray:
        pose = case.mocap_from_scan @ case.head_pose[t]
        return V @ pose[:3, :3].T + pose[:3, 3]

    renderer = FootageRenderer(F, cameras)
    noise_rng = np.random.default_rng(np.random.SeedSequence([seed, 25]))
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=video_frames.size, desc="detail footage", unit="frame")
    others: list[list[np.ndarray]] = [[] for _ in cameras[1:]]

    def frames() -> Any:
        for t in video_frames:
            t = int(t)
            X = world(t, G[t].astype(np.float64))
            N = vertex_normals(X, F)
            caster = RayCaster(X, F)
            lit = np.stack([caster.lit(X, light, normals=N) for light in lights.lights])
            occlusion = ambient_occlusion(X, F, rays=ao_rays, seed=seed + t)
            shading = shade_skin(X, N, reflectance, lights, eyes, lit=lit, occlusion=occlusion, appearance=appearance)
            if appearance == "independent":
                shading = shading._replace(irradiance=subsurface_blur(shading.irradiance, F))
            images = renderer.render(X, skin_radiance(shading, flush.albedo(layers.albedo, t), reflectance))
            if markers_drawn and M:
                centres = case.noiseless_markers[t, :M]
                colour = np.clip(MARKER_ALBEDO * shading.irradiance[case.marker_vertices], 0.0, 1.0)
                for c, cam in enumerate(cameras):
                    seen = caster.visible(centres, cam, tolerance_mm=MARKER_RADIUS_MM)
                    at = cam.project(centres)
                    radius = cam.K[0, 0] * MARKER_RADIUS_MM / np.maximum(at.depth, 1e-9)
                    images[c] = draw_markers(images[c], at.pixels[seen], radius[seen], colour[seen])
            # as a camera writes them: 8-bit files sRGB-encoded, 16-bit files linear
            coded = [quantize(encode(sensor_noise(img, rng=noise_rng)), bits=bits) for img in images]
            for kept, image in zip(others, coded[1:]):
                kept.append(image)
            if bar is not None:
                bar.update(1)
            yield coded[0]

    videos = tuple(out / cam.name for cam in cameras)
    try:
        write_image_sequence(videos[0], frames())
        for folder_k, kept in zip(videos[1:], others):
            write_image_sequence(folder_k, kept)
    finally:
        if bar is not None:
            bar.close()
        renderer.close()
    video_rate = MOCAP_RATE_HZ / video_every
    take = write_take_files(out, scan, case, cameras, video_rate_hz=video_rate, first_mocap_frame=first_mocap_frame)
    lights_path = out / "lights.json"
    write_light_file(lights_path, lights)
    footage_path = out / "footage.json"
    atomic_write_text(footage_path, json.dumps({
        "video_rate_hz": video_rate, "mocap_rate_hz": MOCAP_RATE_HZ, "first_mocap_frame": int(first_mocap_frame),
        "video_every": int(video_every), "video_frames": int(video_frames.size), "bits": bits, "response": "srgb" if bits == 8 else "linear",
        "sensor": SENSOR_DEFAULTS, "ao_rays": int(ao_rays), "appearance": appearance,
        "detail_edge_mm": detail_edge_mm, "scan_vertices": int(mesh.n_vertices),
        "lighting": "lights.json: radiance = k_d albedo (ambient A + sum_l lit E max(0, n.l)) + specular"
                    + (" (Phong: k_s sum_l lit E max(0, r.e)^alpha)" if appearance == "phong"
                       else " (GGX, Schlick Fresnel F0 0.028, wrapped diffuse blurred as subsurface scattering)"),
        "reflectance_columns": (["k_d_scale", "k_s", "alpha"] if appearance == "phong"
                                else ["k_d_scale", "specular_scale", "roughness"]),
        "region_reflectance": {k: list(v) for k, v in REGION_REFLECTANCE[appearance].items()},
        "flush_tint": list(flush.tint), "markers_drawn": bool(markers_drawn), "marker_radius_mm": MARKER_RADIUS_MM,
        "marker_albedo": MARKER_ALBEDO,
    }, indent=1))
    marker_mask = np.zeros(mesh.n_vertices, dtype=bool)
    if M:
        from scipy.spatial import cKDTree

        near = cKDTree(rest[case.marker_vertices]).query(rest, distance_upper_bound=MARKER_RADIUS_MM + _MARKER_MARGIN_MM)
        marker_mask = np.isfinite(near[0])
    truth_path = out / "truth.npz"
    arrays = {
        "vertices": G, "without_detail": L, "detail_height": detailed.heights, "detail_mask": detailed.mask,
        "texture_height": texture.astype(np.float32), "albedo": layers.albedo.astype(np.float32),
        "reflectance": reflectance, "region_labels": labels, "region_names": np.array(sample.region_names),
        "flush_level": flush.level, "flush_weight": flush.weight.astype(np.float32), "flush_tint": flush.tint,
        "marker_mask": marker_mask, "freckle_mask": layers.freckles > 0.02, "mole_mask": layers.moles > 0.02,
        "brow_mask": layers.brows, "marker_vertices": np.asarray(case.marker_vertices),
        "head_pose": np.asarray(case.head_pose), "mocap_from_scan": np.asarray(case.mocap_from_scan),
        "video_mocap_frames": video_frames, "units": np.array("mm"), "rate": np.array(MOCAP_RATE_HZ),
        "video_rate": np.array(video_rate), "appearance": np.array(appearance),
        "curve_names": np.array(lines.names), "curve_kinds": np.array(lines.kinds),
        "activation": detailed.activation, "depths": detailed.depths, "widths": detailed.widths,
        "curve_points": detailed.curve_points,
    }
    with atomic_path(truth_path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
    return DetailFiles(take.scan, take.markers, take.map, truth_path, take.cameras, take.calibrations, videos,
                       lights_path, footage_path)
