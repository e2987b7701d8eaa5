"""Render a face as the wrinkle cameras see it: uniform sky light with self-shadowing, lens distortion, sensor noise.

The renderer was chosen by measurement (``docs/synthetic_data.md``,
"Footage with ground truth"): the skin is Lambertian under a uniform sky, so
its radiance is ``albedo * L_sky * A`` with ``A`` the cosine-weighted
visibility of the sky (ambient occlusion, the integral of Bickel et al.'s
eq. 6 over the true surface); ``A`` is computed per vertex by Embree ray
casting (``embreex``) against the whole mesh, and the mesh is rasterised by
OpenGL on Mesa's llvmpipe (``moderngl`` on a headless EGL context, CPU
only), 4x multisampled. The image is rendered undistorted over a slightly
wider view and resampled through OpenCV's distortion model
(``cv2.undistortPoints`` + ``cv2.remap``), then the sensor adds shot and read
noise and quantises.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any, NamedTuple

import numpy as np

from .._threads import available_cores
from ..errors import InputError
from ..typing import FloatArray, IntArray
from ..validate import as_faces, as_vertices
from ..mesh.vertex_normals import vertex_normals

__all__ = ["FootageRenderer", "ambient_occlusion", "sensor_noise", "quantize", "SENSOR_DEFAULTS"]

SENSOR_DEFAULTS = {"full_well_electrons": 12000.0, "read_noise_electrons": 12.0}
"""A machine-vision CCD like the paper's Basler cameras: photo-electrons at full scale, read noise (electrons RMS)."""

_GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))


def _embree_scene(V: FloatArray, F: IntArray) -> Any:
    """An Embree scene for occlusion queries (first hits with exact points: :func:`facecap.cameras.ray_cast`)."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, np.ascontiguousarray(V[F], dtype=np.float32))
    return scene


def _cosine_directions(count: int) -> FloatArray:
    """(count, 3) cosine-weighted hemisphere directions about +z, stratified (Fibonacci spiral)."""
    i = np.arange(count) + 0.5
    r = np.sqrt(i / count)  # equal-area rings of the unit disc, lifted to the hemisphere (Malley's method)
    phi = i * _GOLDEN_ANGLE
    return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1.0 - r * r)], axis=1)


def ambient_occlusion(
    V: FloatArray,
    F: IntArray,
    *,
    rays: int = 64,
    offset_mm: float = 0.005,
    seed: int = 0,
    batch_vertices: int = 32768,
) -> FloatArray:
    """Cosine-weighted sky visibility at each vertex: the Lambertian irradiance under a uniform sky, over its maximum.

    Parameters
    ----------
    V : (n, 3) float array, mm
    F : (m, 3) int64 array
        Consistently oriented triangles; normals point out of the skin.
    rays : int, default 64
        Rays per vertex: a stratified cosine-weighted set (Fibonacci spiral),
        turned about the normal by a seeded random angle per vertex.
    offset_mm : float, default 0.005
        Rays start this far above the vertex along its normal (Embree
        works in float32; far below any wrinkle).
    seed : int, default 0
    batch_vertices : int, default 32768
        Vertices per batch of rays (bounds memory).

    Returns
    -------
    (n,) float64 array in [0, 1]
        1 where the whole sky is seen.

    Notes
    -----
    ``A(x) = (1 / pi) integral_Omega V(x, w) (n . w) dw`` (Bickel et al.
    2007, eq. 6, over the real surface), estimated as the fraction of
    cosine-distributed rays that escape.
    """
    V = as_vertices(V, name="V")
    F = as_faces(F, V.shape[0], name="F")
    n = V.shape[0]
    N = vertex_normals(V, F, np.arange(n))
    N = np.where(np.isfinite(N), N, [0.0, 0.0, 1.0])
    helper = np.where(np.abs(N[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    tangent = np.cross(N, helper)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    bitangent = np.cross(N, tangent)
    angle = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, n)
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    t1, t2 = c * tangent + s * bitangent, -s * tangent + c * bitangent
    local = _cosine_directions(int(rays))
    scene = _embree_scene(V, F)
    visible = np.empty(n)

    def occlusion(a: int) -> None:
        b = slice(a, a + batch_vertices)
        d = (local[None, :, :1] * t1[b, None] + local[None, :, 1:2] * t2[b, None] + local[None, :, 2:] * N[b, None])
        o = np.broadcast_to((V[b] + offset_mm * N[b])[:, None], d.shape)
        blocked = scene.run(np.ascontiguousarray(o.reshape(-1, 3), dtype=np.float32),
                            np.ascontiguousarray(d.reshape(-1, 3), dtype=np.float32), query="OCCLUDED")
        visible[b] = (np.asarray(blocked).reshape(-1, local.shape[0]) < 0).mean(axis=1)

    # embreex lets go of the GIL while it traces, so batches on threads use every core (the same rays and
    # answers; 3.7 s instead of 5.1 s at 148k vertices on 2 cores); at most 8 batches in flight bound the
    # memory (about 50 MB each at 64 rays)
    with ThreadPoolExecutor(max_workers=min(8, available_cores())) as pool:
        list(pool.map(occlusion, range(0, n, batch_vertices)))
    return visible


def sensor_noise(
    image: FloatArray,
    *,
    rng: np.random.Generator,
    full_well_electrons: float = SENSOR_DEFAULTS["full_well_electrons"],
    read_noise_electrons: float = SENSOR_DEFAULTS["read_noise_electrons"],
) -> FloatArray:
    """What a linear sensor records of an image of expected values in [0, 1] (1 = full well).

    Parameters
    ----------
    image : float array, values in [0, 1]
        Expected signal, as a fraction of full scale.
    rng : numpy.random.Generator
    full_well_electrons : float, default 12000
        Photo-electrons at full scale.
    read_noise_electrons : float, default 12
        Read noise, electrons RMS.

    Returns
    -------
    float64 array, same shape, clipped to [0, 1]

    Notes
    -----
    ``e ~ Poisson(x N_fw)`` (shot noise) ``+ N(0, sigma_r^2)`` (read noise),
    recorded as ``e / N_fw``: mean ``x``, variance ``x / N_fw + (sigma_r / N_fw)^2``
    before clipping.
    """
    x = np.clip(np.asarray(image, dtype=np.float64), 0.0, None)
    electrons = rng.poisson(x * full_well_electrons).astype(np.float64)
    electrons += rng.normal(scale=read_noise_electrons, size=x.shape)
    return np.clip(electrons / full_well_electrons, 0.0, 1.0)


def quantize(image: FloatArray, *, bits: int = 8) -> np.ndarray:
    """Values in [0, 1] to ``uint8`` (bits=8) or ``uint16`` (bits=16) codes, rounding to nearest."""
    if bits not in (8, 16):
        raise InputError(f"bits: expected 8 or 16, got {bits!r}")
    top = (1 << bits) - 1
    codes = np.rint(np.clip(image, 0.0, 1.0) * top)
    return codes.astype(np.uint8 if bits == 8 else np.uint16)


_VERTEX_SHADER = """#version 330
uniform vec4 intrinsics;   // fx, fy, cx, cy of the undistorted render, px
uniform vec4 viewport;     // width, height, near, far
in vec3 position;          // camera frame (OpenCV: x right, y down, z forward), mm
in vec3 radiance;
out vec3 colour;
void main() {
    float z = position.z;
    float w = viewport.x, h = viewport.y, n = viewport.z, f = viewport.w;
    // pixel centres at integer (u, v), the top-left pixel at (0, 0): ndc = (2 (u + 0.5) / W) - 1
    float x_clip = (2.0 * intrinsics.x / w) * position.x + ((2.0 * intrinsics.z + 1.0) / w - 1.0) * z;
    float y_clip = (2.0 * intrinsics.y / h) * position.y + ((2.0 * intrinsics.w + 1.0) / h - 1.0) * z;
    float z_clip = (f + n) / (f - n) * z - 2.0 * f * n / (f - n);
    gl_Position = vec4(x_clip, y_clip, z_clip, z);
    colour = radiance;
}
"""
_FRAGMENT_SHADER = """#version 330
in vec3 colour;
out vec4 result;
void main() { result = vec4(colour, 1.0); }
"""


class _View(NamedTuple):
    K: FloatArray  # undistorted render intrinsics
    size: tuple[int, int]  # render (width, height)
    map_x: np.ndarray
    map_y: np.ndarray
    msaa: Any  # multisampled framebuffer (colour + depth), made once: llvmpipe's buffers are large
    resolved: Any  # single-sample framebuffer it resolves into


def _camera_field(camera: Any, name: str) -> Any:
    try:
        return getattr(camera, name)
    except AttributeError:
        raise InputError(f"cameras: expected objects with K, distortion, width, height, R, T; "
                         f"missing {name!r}") from None


class FootageRenderer:
    """Rasterise a vertex-coloured mesh into calibrated cameras, headless on the CPU.

    Parameters
    ----------
    faces : (m, 3) int64 array
    cameras : sequence of Camera
        Each with ``K`` (3, 3), ``distortion`` (OpenCV order), ``width``,
        ``height``, ``R`` (3, 3), ``T`` (3,) mm (``x_cam = R X + T``), e.g.
        :class:`facecap.cameras.Camera`.
    samples : int, default 4
        MSAA samples per pixel.
    near_mm, far_mm : float, default 50, 5000
        Depth range.

    Notes
    -----
    One OpenGL context (EGL, Mesa llvmpipe) per renderer. Positions are moved
    to each camera's frame in float64 before upload, so float32 rounding
    on the rasteriser is that of camera-frame coordinates (about 1e-4 mm at
    1 m), not of mocap-frame ones. Pixels the face does not cover are 0.
    """

    def __init__(self, faces: IntArray, cameras: Sequence[Any], *, samples: int = 4,
                 near_mm: float = 50.0, far_mm: float = 5000.0) -> None:
        import cv2
        import moderngl

        F = np.asarray(faces, dtype=np.int64)
        if F.ndim != 2 or F.shape[1] != 3 or F.size == 0:
            raise InputError(f"faces: expected a non-empty (m, 3) array, got shape {F.shape}")
        self.faces = F
        self.cameras = list(cameras)
        if not self.cameras:
            raise InputError("cameras: expected at least one camera")
        try:
            self._ctx = moderngl.create_context(standalone=True, backend="egl")
        except Exception as exc:  # noqa: BLE001 - moderngl raises bare Exceptions for a missing EGL
            raise InputError(f"cannot open a headless OpenGL context (EGL, Mesa llvmpipe): {exc}") from None
        self._program = self._ctx.program(vertex_shader=_VERTEX_SHADER, fragment_shader=_FRAGMENT_SHADER)
        self._index = self._ctx.buffer(np.ascontiguousarray(F, dtype=np.int32).tobytes())
        self._samples = int(samples)
        self._near, self._far = float(near_mm), float(far_mm)
        self._views = []
        for cam in self.cameras:
            K = np.asarray(_camera_field(cam, "K"), dtype=np.float64)
            dist = np.asarray(_camera_field(cam, "distortion"), dtype=np.float64).ravel()
            W, H = int(_camera_field(cam, "width")), int(_camera_field(cam, "height"))
            u, v = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
            pix = np.stack([u.ravel(), v.ravel()], axis=1)[:, None, :]
            ideal = cv2.undistortPoints(pix, K, dist if dist.size else None).reshape(H, W, 2)
            # the undistorted render: same focal lengths, a principal point and size that hold every ideal ray
            lo, hi = ideal.reshape(-1, 2).min(axis=0), ideal.reshape(-1, 2).max(axis=0)
            fx, fy = K[0, 0], K[1, 1]
            margin = 2.0
            cx, cy = -lo[0] * fx + margin, -lo[1] * fy + margin
            w_r, h_r = int(np.ceil(hi[0] * fx + cx + margin)) + 1, int(np.ceil(hi[1] * fy + cy + margin)) + 1
            Kr = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
            map_x = (ideal[..., 0] * fx + cx).astype(np.float32)
            map_y = (ideal[..., 1] * fy + cy).astype(np.float32)
            msaa = self._ctx.framebuffer(
                color_attachments=[self._ctx.renderbuffer((w_r, h_r), 4, samples=self._samples, dtype="f4")],
                depth_attachment=self._ctx.depth_renderbuffer((w_r, h_r), samples=self._samples))
            resolved = self._ctx.framebuffer(color_attachments=[self._ctx.renderbuffer((w_r, h_r), 4, dtype="f4")])
            self._views.append(_View(Kr, (w_r, h_r), map_x, map_y, msaa, resolved))

    def render(self, vertices: FloatArray, radiance: FloatArray) -> list[np.ndarray]:
        """Images of the mesh in every camera.

        Parameters
        ----------
        vertices : (n, 3) float array, mm
            In the mocap frame the cameras are calibrated in.
        radiance : (n, 3) or (c, n, 3) float array
            Linear RGB radiance of each vertex (interpolated across triangles),
            as a fraction of the sensor's full scale: one for every camera, or
            one per camera (view-dependent shading, a specular highlight).

        Returns
        -------
        list of (height, width, 3) float32 arrays
            Linear, one per camera, distorted as the lens does; 0 off the face.
        """
        import cv2
        import moderngl

        X = as_vertices(vertices, name="vertices")
        C = np.asarray(radiance, dtype=np.float32)
        if C.shape == X.shape:
            C = np.broadcast_to(C, (len(self.cameras),) + X.shape)
        if C.shape != (len(self.cameras),) + X.shape:
            raise InputError(f"radiance: expected shape {X.shape} or {(len(self.cameras),) + X.shape}, got {C.shape}")
        if int(self.faces.max()) >= X.shape[0]:
            raise InputError(f"vertices: {X.shape[0]} rows, but the faces index up to {int(self.faces.max())}")
        images = []
        ctx = self._ctx
        for cam, view, C_cam in zip(self.cameras, self._views, C):
            Xc = X @ np.asarray(cam.R, dtype=np.float64).T + np.asarray(cam.T, dtype=np.float64).ravel()
            data = np.hstack([Xc.astype(np.float32), C_cam])
            vbo = ctx.buffer(np.ascontiguousarray(data).tobytes())
            vao = ctx.vertex_array(self._program, [(vbo, "3f 3f", "position", "radiance")], self._index)
            w_r, h_r = view.size
            self._program["intrinsics"].value = (view.K[0, 0], view.K[1, 1], view.K[0, 2], view.K[1, 2])
            self._program["viewport"].value = (float(w_r), float(h_r), self._near, self._far)
            msaa, resolved = view.msaa, view.resolved
            msaa.use()
            ctx.enable(moderngl.DEPTH_TEST)
            ctx.disable(moderngl.CULL_FACE)
            ctx.clear(0.0, 0.0, 0.0, 1.0)
            vao.render(moderngl.TRIANGLES)
            ctx.copy_framebuffer(resolved, msaa)
            raw = np.frombuffer(resolved.read(components=3, dtype="f4"), dtype=np.float32).reshape(h_r, w_r, 3)
            # row 0 of the framebuffer is v = 0: the projection maps v to ndc y without a flip
            images.append(cv2.remap(raw, view.map_x, view.map_y, cv2.INTER_LINEAR,
                                    borderMode=cv2.BORDER_CONSTANT, borderValue=0))
            vao.release()
            vbo.release()
        return images

    def close(self) -> None:
        """Release the OpenGL context and everything made in it."""
        self._ctx.release()
