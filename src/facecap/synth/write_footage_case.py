"""A capture case with wrinkle footage and its truth: scan, take, calibrated video of painted wrinkles, truth."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..io.atomic_write import atomic_path, atomic_write_text
from ..io.write_markers import write_markers
from ..io.write_mesh import write_mesh
from ..typing import FloatArray
from ..mesh.vertex_normals import vertex_normals
from .generate_performance import SyntheticCase, generate_performance
from ..io.ict_sample import IctSample, load_ict_sample
from .render_footage import SENSOR_DEFAULTS, FootageRenderer, ambient_occlusion, quantize, sensor_noise
from .skin_albedo import SkinRegions, skin_albedo
from .wrinkle_paint import PAINT_COLORS, paint_wrinkles
from .wrinkle_scan import SubdividedScan, carry_labels, refine_near, subdivide_scan
from .wrinkles import add_wrinkles, place_wrinkles, wrinkle_expression_curves, wrinkle_heights
from .write_synthetic_case import correspondence_json

__all__ = ["FootageFiles", "TakeFiles", "stage_cameras", "write_footage_case", "write_take_files", "MOCAP_RATE_HZ",
           "VIDEO_RATE_HZ"]

MOCAP_RATE_HZ = 50.0
"""Mocap rate of the generated takes: the paper's 50 fps motion cameras."""
VIDEO_RATE_HZ = 12.5
"""Rate of the wrinkle cameras: the paper's 12.5 fps, exactly a quarter of the mocap rate."""
IMAGE_SIZE = (1384, 1038)
"""(width, height) of the paper's high-resolution Basler cameras."""
EXPOSURE = 1.3
"""Linear radiance of a white, fully lit surface, as a fraction of full scale (skin then peaks near 0.7)."""
_DISTORTION = (-0.10, 0.12, 4e-4, -3e-4, 0.0)  # k1 k2 p1 p2 k3: a mild barrel, as a 25 mm C-mount lens has
RENDER_EDGE_MM = 0.3
"""Longest edge of the mesh the footage is rendered from, around the wrinkles (see ``write_footage_case``): what
both wrinkle benchmarks measure on and ``facecap synth --footage``'s default; ``write_footage_case`` itself
defaults to the scan (None), which keeps the test suite's small takes fast."""
MIN_RENDER_EDGE_MM = 0.05
"""Shortest refinement edge accepted, against a slip of the unit: the refined vertices grow as the inverse square of
the edge (about 300k added around the default scan's wrinkles at 0.3 mm, so some ten million at 0.05 mm)."""


class FootageFiles(NamedTuple):
    """Paths of a written footage case."""

    scan: Path
    markers: Path
    map: Path
    truth: Path
    cameras: Path
    calibrations: tuple[Path, ...]
    videos: tuple[Path, ...]
    masks: tuple[Path, ...]
    footage: Path


class TakeFiles(NamedTuple):
    """Paths of what every footage case holds beside its video (:func:`write_take_files`)."""

    scan: Path
    markers: Path
    map: Path
    cameras: Path
    calibrations: tuple[Path, ...]


def write_take_files(out: Path, scan: Any, case: SyntheticCase, cameras: Any, *, video_rate_hz: float,
                     first_mocap_frame: int) -> TakeFiles:
    """Write ``scan.obj``, ``take.c3d``, ``map.json``, ``cameras.json`` and ``calibration_<cam>.yml`` into ``out``.

    ``cameras.json`` is the facecap camera file (the footage's rate and the mocap frame of video
    frame 0); the calibrations are OpenCV FileStorage files, one a camera.
    """
    from ..cameras import CameraSetup, write_camera_file, write_opencv_calibration

    calibrations = []
    for cam in cameras:
        calibrations.append(out / f"calibration_{cam.name}.yml")
        write_opencv_calibration(calibrations[-1], cam)
    cameras_path = out / "cameras.json"
    write_camera_file(cameras_path, CameraSetup(tuple(cameras), video_rate_hz=video_rate_hz,
                                                first_mocap_frame=float(first_mocap_frame)))
    scan_path = out / "scan.obj"
    write_mesh(scan, scan_path)
    markers_path = out / "take.c3d"
    write_markers(case.markers, markers_path)
    map_path = out / "map.json"
    atomic_write_text(map_path, correspondence_json(case.correspondence))
    return TakeFiles(scan_path, markers_path, map_path, cameras_path, tuple(calibrations))


def _look_at(centre: FloatArray, target: FloatArray, up: FloatArray) -> tuple[FloatArray, FloatArray]:
    """R, T (OpenCV: x right, y down, z forward) of a camera at ``centre`` looking at ``target``."""
    z = target - centre
    z /= np.linalg.norm(z)
    y = -(up - (up @ z) * z)
    y /= np.linalg.norm(y)
    x = np.cross(y, z)
    R = np.stack([x, y, z])
    return R, -R @ centre


def stage_cameras(
    scan_vertices: FloatArray,
    landmarks: Any,
    mocap_from_scan: FloatArray,
    *,
    image_size: tuple[int, int] = IMAGE_SIZE,
    distance_mm: float = 900.0,
    azimuth_deg: float = 22.0,
    elevation_deg: float = 6.0,
    field_height_mm: float = 235.0,
    names: tuple[str, str] = ("cam_left", "cam_right"),
) -> list[Any]:
    """The two wrinkle cameras, front-left and front-right of the face at rest, in the mocap frame.

    Parameters
    ----------
    scan_vertices : (n, 3) float array, mm
        The face at rest in the scan's frame (ICT: x to the subject's left, y up, z out).
    landmarks : (68,) int array
        Its ICT landmarks (the face centre is the middle of the nose bridge and chin).
    mocap_from_scan : (4, 4) float array
        The take's rigid transform from the scan frame to the mocap frame.
    image_size : (int, int), default (1384, 1038)
        (width, height), px.
    distance_mm : float, default 900
    azimuth_deg : float, default 22
        Each camera this far to the subject's left ('cam_left') or right of straight ahead.
    elevation_deg : float, default 6
    field_height_mm : float, default 235
        Height of the face-centre plane the image spans (sets the focal length).
    names : (str, str), default ('cam_left', 'cam_right')

    Returns
    -------
    list of facecap.cameras.Camera
        With OpenCV distortion ``(k1, k2, p1, p2, k3) = (-0.10, 0.12, 4e-4, -3e-4, 0)``.
    """
    from ..cameras import Camera

    V = np.asarray(scan_vertices, dtype=np.float64)
    lm = np.asarray(landmarks)
    target = 0.5 * (V[lm[27]] + V[lm[8]]) + np.array([0.0, 12.0, 0.0])  # lifted: the forehead matters most
    width, height = image_size
    f = height * distance_mm / field_height_mm
    K = np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0.0, 0.0, 1.0]])
    M = np.asarray(mocap_from_scan, dtype=np.float64)
    cams = []
    for name, sign in zip(names, (1.0, -1.0)):
        az, el = np.deg2rad(sign * azimuth_deg), np.deg2rad(elevation_deg)
        direction = np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])
        R_s, T_s = _look_at(target + distance_mm * direction, target, np.array([0.0, 1.0, 0.0]))
        # x_cam = R_s X_scan + T_s and X_scan = M^-1 X_mocap
        R = R_s @ M[:3, :3].T
        T = T_s - R @ M[:3, 3]
        cams.append(Camera(name, K=K, distortion=np.array(_DISTORTION), width=width, height=height, R=R, T=T))
    return cams


def _fine_regions(sample: IctSample, upsample: Any, scan_vertices: FloatArray) -> SkinRegions:
    """The sample's face regions carried to the fine mesh: each new vertex takes its heaviest parent's."""
    return SkinRegions(carry_labels(upsample, sample.region_labels), sample.region_names,
                       scan_vertices[sample.landmarks[48:60]])


def _render_mesh(fine: SubdividedScan, wrinkle_mask: np.ndarray, max_edge_mm: float | None) -> SubdividedScan:
    """The mesh the footage is rendered from: the scan, refined around its wrinkles (``None``: the scan itself)."""
    mesh = fine.mesh
    if max_edge_mm is None:
        return SubdividedScan(mesh, sp.identity(mesh.n_vertices, format="csr"), mesh.n_vertices)
    near = np.zeros(mesh.n_vertices, dtype=bool)
    near[np.unique(mesh.faces[np.any(wrinkle_mask[mesh.faces], axis=1)])] = True  # the influence and one ring
    return refine_near(mesh, near, max_edge_mm=max_edge_mm)


def _render_frames(render: SubdividedScan, scan_faces: np.ndarray, large: np.ndarray, wrinkled: np.ndarray,
                   curves: Any, activation: FloatArray, frames: np.ndarray) -> Any:
    """``frame(t)``: the rendered mesh's vertices at mocap frame ``t`` (one of ``frames``; scan frame, mm).

    The large scale is carried linearly (the refined surface is the scan's), the wrinkles'
    heights are evaluated at the new vertices along the scan's vertex normals carried the same
    way (as :func:`~facecap.synth.wrinkles.add_wrinkles` does at the scan's), and the scan's own
    vertices are exactly those of the truth.
    """
    S = render.upsample
    n = render.n_original
    new = np.arange(n, render.mesh.n_vertices)
    _, moving, heights = wrinkle_heights(curves, render.mesh.vertices[new], activation[frames])
    moving = new[moving]
    carry = S[moving]
    support = np.unique(carry.indices)
    carry = carry[:, support]
    row = {int(t): i for i, t in enumerate(frames)}

    def frame(t: int) -> FloatArray:
        X = large[t].astype(np.float64)
        V = S @ X
        V[:n] = wrinkled[t]
        if moving.size:
            normals = carry @ vertex_normals(X, scan_faces, support)
            normals /= np.linalg.norm(normals, axis=1, keepdims=True)
            V[moving] += heights[row[int(t)]][:, None] * normals
        return V

    return frame


def _paint_masks(renderer: FootageRenderer, world: FloatArray, stripe_colors: np.ndarray,
                 n_colors: int) -> list[np.ndarray]:
    """Per camera, a (H, W) uint8 label image of frame 0: 1 + paint index where a paint covers the pixel, else 0."""
    coverage = []
    for k in range(n_colors):
        radiance = np.zeros((world.shape[0], 3))
        radiance[stripe_colors == k] = 1.0
        coverage.append([img[..., 0] for img in renderer.render(world, radiance)])
    out = []
    for cam in range(len(renderer.cameras)):
        stack = np.stack([coverage[k][cam] for k in range(n_colors)])
        label = np.argmax(stack, axis=0).astype(np.uint8) + 1
        label[stack.max(axis=0) < 0.5] = 0
        out.append(label)
    return out


def write_footage_case(
    folder: str | Path,
    *,
    n_frames: int = 100,
    seed: int = 0,
    identity: Any = None,
    curves: Any = None,
    levels: int = 2,
    image_size: tuple[int, int] = IMAGE_SIZE,
    ao_rays: int = 64,
    render_edge_mm: float | None = None,
    bits: int = 8,
    n_markers: int | None = None,
    first_mocap_frame: int = 0,
    cameras: Any = None,
    case: SyntheticCase | None = None,
    sample: IctSample | None = None,
    progress: bool = False,
) -> FootageFiles:
    """Generate a take with wrinkles and render its wrinkle footage, with the whole truth.

    The large scale is :func:`~facecap.synth.generate_performance.generate_performance`
    at 50 Hz on the ICT face, carried to the scan subdivided ``levels`` times
    (:func:`~facecap.synth.wrinkle_scan.subdivide_scan`); the wrinkles of
    :func:`~facecap.synth.wrinkles.place_wrinkles` are added on top
    (:func:`~facecap.synth.wrinkles.add_wrinkles`), painted
    (:func:`~facecap.synth.wrinkle_paint.paint_wrinkles`) and filmed at
    12.5 fps (every 4th mocap frame, the first at mocap frame 0) by the two
    cameras of :func:`stage_cameras`, under a uniform sky with ambient
    occlusion (:mod:`~facecap.synth.render_footage`), with shot and read
    noise. The markers come from the large scale: the wrinkles are finer
    than the markers and do not move them.

    Parameters
    ----------
    folder : str or Path
        Created if needed.
    n_frames : int, default 100
        Mocap frames (50 Hz); the footage has ``(n_frames - 1) // 4 + 1`` frames.
    seed : int, default 0
        The take, the wrinkles, the skin and the sensor noise all follow from it.
    curves : {None, 'wrinkles', 'smooth', 'speech', 'real', 'rapid_asymmetric'} or (T, 53) float array, optional
        The expression weights. None or 'wrinkles' (default):
        :func:`~facecap.synth.wrinkles.wrinkle_expression_curves` (brow
        raise, frown, smile and squint in turn); otherwise passed to
        :func:`~facecap.synth.generate_performance.generate_performance`.
    identity, n_markers
        Passed to :func:`~facecap.synth.generate_performance.generate_performance`.
    levels : int, default 2
        Subdivision levels of the scan (2: 148,402 vertices).
    image_size : (int, int), default (1384, 1038)
    ao_rays : int, default 64
        Ambient-occlusion rays per vertex (of the rendered mesh).
    render_edge_mm : float or None, default None
        With a length (:data:`RENDER_EDGE_MM`, 0.3, is what ``benchmarks/bench_cross_sections.py``
        measures), the footage shows the wrinkles of the truth, not their sampling at the scan's
        vertices: it is rendered from the scan refined around the wrinkles (red-green midpoint
        subdivision, :func:`~facecap.synth.wrinkle_scan.refine_near`) until no edge there is
        longer than this, with the wrinkles' heights evaluated at the new vertices. On the scan
        itself (``None``) a valley a few vertices wide shades as a shallower one: at the default
        scan's 0.7-0.9 mm edges a 1.2 mm wide valley looks 13-25 % shallower to the fit of eq. 6
        (``docs/synthetic_data.md``). The scan's own vertices are rendered where they are in
        ``truth.npz``.
    bits : {8, 16}, default 8
        PNG depth. The sensor response is linear (no gamma): a code is proportional to radiance.
    first_mocap_frame : int, default 0
        The mocap frame at which video frame 0 is exposed (0-3: the synchronisation offset);
        video frame ``j`` is mocap frame ``first_mocap_frame + 4 j``.
    cameras : sequence of facecap.cameras.Camera, optional
        Cameras in the take's mocap frame instead of :func:`stage_cameras`'
        two (any number, distinct names; ``image_size`` is then theirs).
    case : SyntheticCase, optional
        A take to use instead of generating one (its rate must be 50 Hz).
    sample : IctSample, optional
    progress : bool, default False
        A tqdm bar over the rendered frames.

    Returns
    -------
    FootageFiles

    Raises
    ------
    InputError
        On a bad option (``bits``, ``image_size``, ``ao_rays``, ``levels``, the
        take's options) or a ``case`` not at 50 Hz.

    Notes
    -----
    Every file is written atomically and ``truth.npz`` last: a folder without
    it is an interrupted run. Written: ``scan.obj`` (the fine scan), ``take.c3d``, ``map.json``,
    ``cameras.json`` (the facecap camera file: both cameras, 12.5 fps, first
    mocap frame 0), ``calibration_<cam>.yml`` (OpenCV FileStorage),
    ``<cam>/frame_000000.png ...``, ``mask_<cam>.png`` (frame 0: 1 + paint
    index where a paint is, 0 elsewhere: what a user would paint),
    ``footage.json`` (paints, sensor, exposure, response) and ``truth.npz``:
    ``vertices`` (T, n, 3) float32 mm at the mocap rate, ``large_scale``
    (T, n, 3) (the same without wrinkles), ``wrinkle_mask`` (n,) bool,
    ``head_pose`` (T, 4, 4), ``mocap_from_scan``, ``units``, ``rate``,
    ``video_rate``, ``curve_names``, ``curve_kinds``, ``curve_rest_points``
    (c, k, 3), ``curve_faces`` (c, k), ``curve_barycentric`` (c, k, 3),
    ``curve_points`` (T, c, k, 3) (the valley line on ``vertices``, scan
    frame), ``depths`` and ``widths`` (T, c, k) mm (``widths``: the half-width
    from the valley line to the profile's zero crossing), ``activation``
    (T, c), ``curve_colors`` (c, 3) linear RGB, ``paint_index`` (c,).
    """
    from ..cameras import write_image, write_image_sequence

    if bits not in (8, 16):
        raise InputError(f"bits: expected 8 or 16, got {bits!r}")
    try:
        width, height = (int(x) for x in image_size)
    except (TypeError, ValueError):
        raise InputError(f"image_size: expected (width, height) in pixels, got {image_size!r}") from None
    if width < 16 or height < 16 or (width, height) != tuple(image_size):
        raise InputError(f"image_size: expected two integers >= 16, got {image_size!r}")
    if isinstance(ao_rays, bool) or not isinstance(ao_rays, (int, np.integer)) or ao_rays < 1:
        raise InputError(f"ao_rays: expected an integer >= 1, got {ao_rays!r}")
    if render_edge_mm is not None and (isinstance(render_edge_mm, bool) or not isinstance(render_edge_mm, (int, float))
                                       or not MIN_RENDER_EDGE_MM <= render_edge_mm < np.inf):
        raise InputError(f"render_edge_mm: expected None or a finite length >= {MIN_RENDER_EDGE_MM:g} mm, "
                         f"got {render_edge_mm!r}")
    if isinstance(first_mocap_frame, bool) or not isinstance(first_mocap_frame, (int, np.integer)) \
            or not 0 <= first_mocap_frame < 4:
        raise InputError(f"first_mocap_frame: expected an integer in 0..3, got {first_mocap_frame!r}")
    if cameras is not None:
        cameras = list(cameras)
        names = [getattr(cam, "name", None) for cam in cameras]
        if not cameras or len(set(names)) != len(names):
            raise InputError("cameras: expected at least one camera, with distinct names")
    sample = load_ict_sample() if sample is None else sample
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    if case is None:
        if curves is None or (isinstance(curves, str) and curves == "wrinkles"):
            curves = wrinkle_expression_curves(n_frames, sample.expression_names, rate=MOCAP_RATE_HZ, seed=seed)
        case = generate_performance(n_frames=n_frames, rate=MOCAP_RATE_HZ, identity=identity, curves=curves,
                                    n_markers=n_markers, seed=seed, sample=sample)
    elif abs(case.markers.rate - MOCAP_RATE_HZ) > 1e-9:
        raise InputError(f"case: rate {case.markers.rate} Hz; the footage needs a {MOCAP_RATE_HZ:g} Hz take")
    T = case.truth_vertices.shape[0]
    fine = subdivide_scan(case.scan, levels=levels)
    mesh, S = fine.mesh, fine.upsample
    rest = mesh.vertices
    large = np.empty((T, mesh.n_vertices, 3), dtype=np.float32)
    for t0 in range(0, T, 16):
        block = np.asarray(case.truth_vertices[t0 : t0 + 16], dtype=np.float64)
        flat = S @ np.moveaxis(block, 0, 1).reshape(block.shape[1], -1)
        large[t0 : t0 + 16] = np.moveaxis(flat.reshape(mesh.n_vertices, block.shape[0], 3), 1, 0)
    wrinkle_curves = place_wrinkles(mesh, sample, seed=seed)
    wrinkled = add_wrinkles(large, mesh.faces, wrinkle_curves, case.weights, rest=rest)
    video_frames = np.arange(first_mocap_frame, T, 4)
    if video_frames.size == 0:
        raise InputError(f"n_frames: {T} mocap frames hold no video frame from mocap frame {first_mocap_frame}")
    render = _render_mesh(fine, wrinkled.mask, render_edge_mm)
    render_faces = render.mesh.faces
    render_rest = render.mesh.vertices
    render_frames = _render_frames(render, mesh.faces, large, wrinkled.vertices, wrinkle_curves, wrinkled.activation,
                                   video_frames)
    regions = _fine_regions(sample, (render.upsample @ S).tocsr(), render_rest)
    painted = paint_wrinkles(wrinkle_curves, render_rest, skin_albedo(render_rest, seed=seed, region=regions))
    if cameras is None:
        cameras = stage_cameras(rest, sample.landmarks, case.mocap_from_scan, image_size=(width, height))
    renderer = FootageRenderer(render_faces, cameras)
    noise_rng = np.random.default_rng(np.random.SeedSequence([seed, 12_5]))
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=video_frames.size, desc="footage", unit="frame")

    def world(t: int, V: FloatArray) -> FloatArray:
        M = case.mocap_from_scan @ case.head_pose[t]
        return V @ M[:3, :3].T + M[:3, 3]

    # the first camera's frames stream to disk as they are rendered; the others wait in memory (their
    # ambient occlusion is the same, so each frame is shaded once for every camera)
    others: list[list[np.ndarray]] = [[] for _ in cameras[1:]]

    def first_camera_frames() -> Any:
        for t in video_frames:
            V = render_frames(int(t))
            occlusion = ambient_occlusion(V, render_faces, rays=ao_rays, seed=seed + int(t))
            images = renderer.render(world(int(t), V), EXPOSURE * painted.albedo * occlusion[:, None])
            coded = [quantize(sensor_noise(img, rng=noise_rng), bits=bits) for img in images]
            for kept, image in zip(others, coded[1:]):
                kept.append(image)
            if bar is not None:
                bar.update(1)
            yield coded[0]

    videos = tuple(out / cam.name for cam in cameras)
    try:
        write_image_sequence(videos[0], first_camera_frames())
        for folder_k, kept in zip(videos[1:], others):
            write_image_sequence(folder_k, kept)
        first = int(video_frames[0])
        masks_img = _paint_masks(renderer, world(first, render_frames(first)),
                                 np.where(painted.stripe >= 0, painted.color_index[painted.stripe], -1),
                                 len(PAINT_COLORS))
    finally:
        if bar is not None:
            bar.close()
        renderer.close()
    masks = []
    for cam, label in zip(cameras, masks_img):
        masks.append(out / f"mask_{cam.name}.png")
        write_image(masks[-1], label)
    take_files = write_take_files(out, mesh, case, cameras, video_rate_hz=VIDEO_RATE_HZ,
                                  first_mocap_frame=first_mocap_frame)
    footage_path = out / "footage.json"
    atomic_write_text(footage_path, json.dumps({
        "video_rate_hz": VIDEO_RATE_HZ, "mocap_rate_hz": MOCAP_RATE_HZ, "first_mocap_frame": int(first_mocap_frame),
        "video_frames": int(video_frames.size), "bits": bits, "response": "linear",
        "exposure": EXPOSURE, "sensor": SENSOR_DEFAULTS, "ao_rays": ao_rays,
        "render_edge_mm": render_edge_mm, "rendered_vertices": int(render.mesh.n_vertices),
        "lighting": "uniform sky, ambient occlusion (cosine-weighted visibility)",
        "paints": {str(i): list(c) for i, c in enumerate(PAINT_COLORS)},
        "mask_labels": "0 = no paint, 1 + i = paint i",
        "wrinkles": {name: int(i) for name, i in zip(wrinkle_curves.names, painted.color_index)},
    }, indent=1))
    truth_path = out / "truth.npz"
    arrays = {
        "vertices": wrinkled.vertices, "large_scale": large, "wrinkle_mask": wrinkled.mask,
        "head_pose": np.asarray(case.head_pose), "mocap_from_scan": np.asarray(case.mocap_from_scan),
        "units": np.array("mm"), "rate": np.array(MOCAP_RATE_HZ), "video_rate": np.array(VIDEO_RATE_HZ),
        "curve_names": np.array(wrinkle_curves.names), "curve_kinds": np.array(wrinkle_curves.kinds),
        "curve_rest_points": wrinkle_curves.points, "curve_faces": wrinkle_curves.faces,
        "curve_barycentric": wrinkle_curves.barycentric, "curve_points": wrinkled.curve_points,
        "depths": wrinkled.depths, "widths": wrinkled.widths, "activation": wrinkled.activation,
        "curve_colors": painted.curve_colors, "paint_index": painted.color_index,
    }
    with atomic_path(truth_path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
    return FootageFiles(take_files.scan, take_files.markers, take_files.map, truth_path, take_files.cameras,
                        take_files.calibrations, videos, tuple(masks), footage_path)
