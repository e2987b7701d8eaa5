"""Streamed export of an animated mesh to USD (``.usdc``), in bounded memory.

Layout of the stage (both modes)::

    /Head            Xform, defaultPrim; time-sampled ``xformOp:transform``
                     when head poses are given (then the mesh is stabilised)
    /Head/Face       Mesh: the scan's polygons, ``primvars:st`` (faceVarying,
                     indexed) when it has UVs, time-sampled ``points`` and
                     ``extent`` in the scan's source unit
    /Head/Looks/Skin Material (UsdPreviewSurface) when the scan has a colour
                     texture: its image ``<stem>_color.png`` beside the file

Why two modes: an Sdf layer keeps every time sample it holds in memory until it
is saved and released, and a ``.usdc`` file is written in one go when its layer
is saved. A long take of a dense scan (700k vertices x 10,000 frames is 84 GB
of float32 points) cannot live in one layer. So:

- **single file** when the whole take is small (points under
  ``single_file_max_bytes``, default 256 MiB): one self-contained ``.usdc``;
- **value clips** otherwise (USD's mechanism for splitting time samples over
  files: ``UsdClipsAPI``): the samples go to clip layers
  ``<stem>_clips/clip_000000.usdc, ...`` of ``clip_frames`` frames each (by
  default as many as fit in ``single_file_max_bytes``), each saved and released
  as soon as it is full, so memory holds at most one clip; a manifest
  ``<stem>_clips/manifest.usdc`` declares the animated attributes; the top
  ``<stem>.usdc`` holds the topology, the stage metadata and the clip-set
  metadata (asset paths, primPath, active, identity times) on ``/Head``.
  Each clip also holds the first frame of the next clip, so values between
  the last frame of one clip and the first of the next still interpolate.
  No default ``points`` are authored in the top layer: a default there would
  win over the clips.

Everything appears atomically on :meth:`UsdPerformanceWriter.close`: clips are
written to a hidden staging folder renamed into place, the top layer to a
hidden sibling renamed onto ``path``; :meth:`UsdPerformanceWriter.abort`
removes them.
"""

from __future__ import annotations

import os
import re
import secrets
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..structures import Mesh
from ..units import mm_per_unit
from .atomic_write import atomic_path
from .usd_material import bind_colour_texture, write_texture_beside

__all__ = ["UsdPerformanceWriter"]

_ROOT = "/Head"
_MESH = "/Head/Face"
_XFORM_OP = "xformOp:transform"
_CLIP_NAME = "clip_{:06d}.usdc"
_MANIFEST = "manifest.usdc"
_OUR_CLIP_FILE = re.compile(r"^(clip_\d{6}\.usdc|manifest\.usdc)$")


def _pxr() -> Any:
    """Import pxr lazily (it costs ~0.3 s); usd-core is a main dependency."""
    from pxr import Gf, Sdf, Usd, UsdGeom, Vt

    return Gf, Sdf, Usd, UsdGeom, Vt


class UsdPerformanceWriter:
    """Write an animated mesh to a ``.usdc`` stage frame block by frame block.

    Parameters
    ----------
    path : str or path-like
        The ``.usdc`` file to write. In clip mode a sibling folder
        ``<stem>_clips/`` is written too (and replaced if it exists).
    mesh : Mesh
        The scan: export polygons (``Mesh.export_polygons()``), UVs and source
        unit. Points are written in ``mesh.source_unit``, with the stage's
        ``metersPerUnit`` set to match (mm 0.001, cm 0.01, m 1, in 0.0254).
    rate : float
        Frame rate of the take in Hz: the stage's ``timeCodesPerSecond`` and
        ``framesPerSecond``. Frame k is time code k (0 .. n_frames - 1).
    n_frames : int
        Number of frames that will be written.
    single_file_max_bytes : int, optional
        Largest take (``n_frames * n_vertices * 12`` bytes of points) written as
        one self-contained file; default 256 MiB. Larger takes use value clips.
    clip_frames : int or None, optional
        Frames per clip layer in clip mode; default None: as many as fit in
        ``single_file_max_bytes`` (at least 1). Giving it forces clip mode
        whenever it is smaller than ``n_frames``.
    subdivision_scheme : {'none', 'catmullClark', 'loop', 'bilinear'}, optional
        The mesh's ``subdivisionScheme``; default ``'none'`` (draw the scan's
        faces as they are).

    Raises
    ------
    InputError
        If an argument is invalid, the UVs do not match the polygons, or the
        destination folder does not exist.

    Notes
    -----
    Memory stays bounded by one clip (about ``single_file_max_bytes``) plus the
    block being written, whatever the take's length. Points are converted to
    float32 ``Vt.Vec3fArray`` with ``FromNumpy`` (no per-vertex Python work).

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from facecap.structures import Mesh
    >>> V = np.array([[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0]], float)
    >>> quad = Mesh(V, [[0, 1, 2], [0, 2, 3]], polygon_sizes=[4], polygon_indices=[0, 1, 2, 3])
    >>> out = os.path.join(tempfile.mkdtemp(), "take.usdc")
    >>> with UsdPerformanceWriter(out, quad, rate=60.0, n_frames=2) as writer:
    ...     writer.write_frames(0, np.stack([V, V + 1.0]))
    >>> from pxr import Usd
    >>> Usd.Stage.Open(out).GetTimeCodesPerSecond()
    60.0
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        mesh: Mesh,
        rate: float,
        n_frames: int,
        *,
        single_file_max_bytes: int = 256 * 2**20,
        clip_frames: int | None = None,
        subdivision_scheme: str = "none",
    ) -> None:
        if not isinstance(mesh, Mesh):
            raise InputError(f"mesh: expected a facecap Mesh, got {type(mesh).__name__}")
        try:
            rate_f = float(rate)
        except (TypeError, ValueError):
            rate_f = float("nan")
        if not np.isfinite(rate_f) or rate_f <= 0:
            raise InputError(f"rate: expected a positive frame rate in Hz, got {rate!r}")
        if not isinstance(n_frames, (int, np.integer)) or int(n_frames) < 1:
            raise InputError(f"n_frames: expected a positive integer, got {n_frames!r}")
        if subdivision_scheme not in ("none", "catmullClark", "loop", "bilinear"):
            raise InputError(
                "subdivision_scheme: expected one of 'none', 'catmullClark', 'loop', 'bilinear', "
                f"got {subdivision_scheme!r}"
            )
        self.path = Path(os.fspath(path))
        if self.path.suffix.lower() != ".usdc":
            raise InputError(f"path: expected a .usdc file name, got {str(self.path)!r}")
        if not self.path.parent.is_dir():
            raise InputError("cannot write: the folder does not exist", path=str(self.path))
        self.mesh = mesh
        self.rate = rate_f
        self.n_frames = int(n_frames)
        self.subdivision_scheme = subdivision_scheme
        self._scale = 1.0 / mm_per_unit(mesh.source_unit)  # mm -> source unit
        self._uv = self._check_uvs(mesh)

        n = mesh.n_vertices
        frame_bytes = 12 * n
        max_bytes = int(single_file_max_bytes)
        if max_bytes < 1:
            raise InputError(f"single_file_max_bytes: expected a positive integer, got {single_file_max_bytes!r}")
        if clip_frames is None:
            per_clip = max(1, max_bytes // frame_bytes)
            self.use_clips = self.n_frames * frame_bytes > max_bytes and per_clip < self.n_frames
        else:
            if not isinstance(clip_frames, (int, np.integer)) or int(clip_frames) < 1:
                raise InputError(f"clip_frames: expected a positive integer, got {clip_frames!r}")
            per_clip = int(clip_frames)
            self.use_clips = per_clip < self.n_frames
        self.clip_frames = per_clip if self.use_clips else self.n_frames

        self.frames_written = 0
        self._head_pose: bool | None = None  # decided by the first block
        self._image_name: str | None = None  # the colour texture's file, written on close
        self._closed = False
        self._layer: Any = None  # single-file layer
        self._clips: dict[int, Any] = {}  # open clip layers by index
        self.clips_dir = self.path.with_name(f"{self.path.stem}_clips")
        self._staging: Path | None = None
        if self.use_clips:
            if self.clips_dir.exists() and not self._is_our_clips_dir(self.clips_dir):
                raise InputError(
                    "exists and holds files facecap did not write; refusing to replace it",
                    path=str(self.clips_dir),
                )
            self._staging = self.path.with_name(f".{self.clips_dir.name}.partial-{secrets.token_hex(4)}")
            self._staging.mkdir()
        else:
            _, Sdf, _, _, _ = _pxr()
            self._layer = Sdf.Layer.CreateAnonymous("performance.usdc")

    # ------------------------------------------------------------------ checks

    def _check_uvs(self, mesh: Mesh) -> tuple[np.ndarray, np.ndarray | None] | None:
        """UVs to export as (uvs, face-varying indices), (uvs, None) for per-vertex, or None."""
        if mesh.uvs is None:
            return None
        uvs = np.asarray(mesh.uvs, dtype=np.float64)
        if uvs.ndim != 2 or uvs.shape[1] != 2:
            raise InputError(f"mesh.uvs: expected shape (u, 2), got {uvs.shape}")
        sizes, _ = mesh.export_polygons()
        if mesh.uv_indices is None:
            if uvs.shape[0] != mesh.n_vertices:
                raise InputError(
                    f"mesh.uvs: without uv_indices expected one UV per vertex ({mesh.n_vertices}), got {uvs.shape[0]}"
                )
            return uvs, None
        idx = np.asarray(mesh.uv_indices, dtype=np.int64)
        if idx.shape != (int(sizes.sum()),):
            raise InputError(
                f"mesh.uv_indices: expected one index per polygon corner ({int(sizes.sum())}), got {idx.shape}"
            )
        if idx.size and (idx.min() < 0 or idx.max() >= uvs.shape[0]):
            raise InputError(f"mesh.uv_indices: indices must lie in [0, {uvs.shape[0]})")
        return uvs, idx

    # ----------------------------------------------------------------- writing

    def _clip_layer(self, index: int) -> Any:
        """The open clip layer ``index``, created with its prim and attribute specs."""
        layer = self._clips.get(index)
        if layer is None:
            _, Sdf, _, _, _ = _pxr()
            layer = Sdf.Layer.CreateNew(str(Path(str(self._staging)) / _CLIP_NAME.format(index)))
            self._declare_animated(layer)
            layer.timeCodesPerSecond = self.rate
            layer.framesPerSecond = self.rate
            self._clips[index] = layer
        return layer

    def _declare_animated(self, layer: Any) -> None:
        """Prim and attribute specs of the animated attributes (clip layers and manifest)."""
        _, Sdf, _, _, _ = _pxr()
        root = Sdf.CreatePrimInLayer(layer, _ROOT)
        root.specifier = Sdf.SpecifierDef
        root.typeName = "Xform"
        mesh = Sdf.CreatePrimInLayer(layer, _MESH)
        mesh.specifier = Sdf.SpecifierDef
        mesh.typeName = "Mesh"
        Sdf.AttributeSpec(mesh, "points", Sdf.ValueTypeNames.Point3fArray)
        Sdf.AttributeSpec(mesh, "extent", Sdf.ValueTypeNames.Float3Array)
        if self._head_pose:
            Sdf.AttributeSpec(root, _XFORM_OP, Sdf.ValueTypeNames.Matrix4d)

    def _save_clip(self, index: int) -> None:
        layer = self._clips.pop(index)
        layer.startTimeCode = float(index * self.clip_frames)
        layer.endTimeCode = float(min((index + 1) * self.clip_frames, self.n_frames - 1))
        if not layer.Save():
            raise InputError("could not save a USD clip layer", path=layer.realPath)
        del layer  # released: its samples leave memory

    def write_frames(self, start: int, vertices_mm: Any, *, head_pose: Any = None) -> None:
        """Append a block of consecutive frames.

        Parameters
        ----------
        start : int
            Index of the block's first frame; must equal the frames written so far.
        vertices_mm : (k, n, 3) float array, mm
            Vertex positions of frames ``start .. start + k - 1`` (stabilised,
            i.e. in head coordinates, when ``head_pose`` is given). Converted
            to the mesh's source unit and float32.
        head_pose : (k, 4, 4) float array or None, optional
            Rigid head transform of each frame mapping head coordinates to
            world, column-vector convention (``x_world = R x + t``, t in mm in
            ``[:3, 3]``), written as the time-sampled ``xformOp:transform`` of
            ``/Head``. Either every block gives it or none does.

        Raises
        ------
        InputError
            If the block is out of order, has the wrong shape, holds
            non-finite values, runs past ``n_frames``, or ``head_pose`` is
            given for some blocks only.
        """
        if self._closed:
            raise InputError("write_frames: the writer is already closed or aborted")
        if int(start) != self.frames_written:
            raise InputError(
                f"start: frames must be written in order: expected frame {self.frames_written}, got {start}"
            )
        n = self.mesh.n_vertices
        block = np.asarray(vertices_mm)
        if block.ndim == 2:
            block = block[None]
        if block.ndim != 3 or block.shape[1:] != (n, 3) or block.shape[0] < 1:
            raise InputError(f"vertices_mm: expected shape (k, {n}, 3), got {np.shape(vertices_mm)}")
        k = block.shape[0]
        if self.frames_written + k > self.n_frames:
            raise InputError(
                f"vertices_mm: {self.frames_written + k} frames would exceed n_frames={self.n_frames}"
            )
        pose = None
        if head_pose is not None:
            pose = np.asarray(head_pose, dtype=np.float64)
            if pose.ndim == 2:
                pose = pose[None]
            if pose.shape != (k, 4, 4) or not np.all(np.isfinite(pose)):
                raise InputError(f"head_pose: expected a finite ({k}, 4, 4) array, got {np.shape(head_pose)}")
        if self._head_pose is None:
            self._head_pose = pose is not None
            if not self.use_clips:
                self._declare_animated(self._layer)
        elif self._head_pose != (pose is not None):
            raise InputError(
                "head_pose: give it for every block or for none "
                f"(the first block {'had' if self._head_pose else 'had no'} head poses)"
            )

        Gf, Sdf, _, _, Vt = _pxr()
        points_path = Sdf.Path(_MESH).AppendProperty("points")
        extent_path = Sdf.Path(_MESH).AppendProperty("extent")
        xform_path = Sdf.Path(_ROOT).AppendProperty(_XFORM_OP)
        for j in range(k):
            frame = np.multiply(block[j], self._scale, dtype=np.float32)
            # Column-wise min/max (fast, unlike a strided axis-0 reduction); NaN and inf show up in them.
            lo = np.array([frame[:, c].min() for c in range(3)], dtype=np.float32)
            hi = np.array([frame[:, c].max() for c in range(3)], dtype=np.float32)
            if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
                raise InputError(f"vertices_mm: frame {start + j} contains NaN or infinite values")
            t = float(start + j)
            points = Vt.Vec3fArray.FromNumpy(frame)
            extent = Vt.Vec3fArray.FromNumpy(np.stack([lo, hi]))
            xform = None
            if pose is not None:
                m = pose[j].copy()
                m[:3, 3] *= self._scale
                xform = Gf.Matrix4d(m.T.tolist())  # USD matrices act on row vectors
            if self.use_clips:
                f = start + j
                targets = [f // self.clip_frames]
                if f % self.clip_frames == 0 and f > 0:
                    targets.insert(0, f // self.clip_frames - 1)  # overlap: next clip's first frame
                layers = [self._clip_layer(c) for c in targets]
            else:
                layers = [self._layer]
            for layer in layers:
                with Sdf.ChangeBlock():
                    layer.SetTimeSample(points_path, t, points)
                    layer.SetTimeSample(extent_path, t, extent)
                    if xform is not None:
                        layer.SetTimeSample(xform_path, t, xform)
            if self.use_clips and len(targets) == 2:
                self._save_clip(targets[0])
        self.frames_written += k

    # ------------------------------------------------------------- finishing

    def _author_top(self, layer: Any) -> None:
        """Topology, UVs, stage metadata (and clip metadata in clip mode) on ``layer``."""
        Gf, Sdf, Usd, UsdGeom, Vt = _pxr()
        stage = Usd.Stage.Open(layer)
        root = UsdGeom.Xform.Define(stage, _ROOT)
        stage.SetDefaultPrim(root.GetPrim())
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
        UsdGeom.SetStageMetersPerUnit(stage, mm_per_unit(self.mesh.source_unit) / 1000.0)
        stage.SetStartTimeCode(0.0)
        stage.SetEndTimeCode(float(self.n_frames - 1))
        stage.SetTimeCodesPerSecond(self.rate)
        stage.SetFramesPerSecond(self.rate)
        layer.documentation = (
            f"facecap performance: {self.mesh.n_vertices} vertices, {self.n_frames} frames at {self.rate:g} Hz, "
            f"unit {self.mesh.source_unit}" + (f", clips in {self.clips_dir.name}/" if self.use_clips else "")
        )
        mesh = UsdGeom.Mesh.Define(stage, _MESH)
        sizes, indices = self.mesh.export_polygons()
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(sizes, dtype=np.int32)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(indices, dtype=np.int32)))
        mesh.CreateSubdivisionSchemeAttr(self.subdivision_scheme)
        mesh.CreatePointsAttr()  # declared; values are time samples (here or in the clips)
        mesh.CreateExtentAttr()
        if self._uv is not None:
            uvs, uv_idx = self._uv
            interp = UsdGeom.Tokens.faceVarying if uv_idx is not None else UsdGeom.Tokens.vertex
            st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, interp)
            st.Set(Vt.Vec2fArray.FromNumpy(np.ascontiguousarray(uvs, dtype=np.float32)))
            if uv_idx is not None:
                st.SetIndices(Vt.IntArray.FromNumpy(np.ascontiguousarray(uv_idx, dtype=np.int32)))
        if self._image_name is not None:
            bind_colour_texture(stage, _MESH, self._image_name)
        if self._head_pose:
            root.AddTransformOp()
        if self.use_clips:
            n_clips = -(-self.n_frames // self.clip_frames)
            rel = f"./{self.clips_dir.name}/"
            clips = Usd.ClipsAPI(root.GetPrim())
            clips.SetClipAssetPaths(Sdf.AssetPathArray([rel + _CLIP_NAME.format(i) for i in range(n_clips)]))
            clips.SetClipPrimPath(_ROOT)
            clips.SetClipActive([(float(i * self.clip_frames), float(i)) for i in range(n_clips)])
            last = float(self.n_frames - 1)
            clips.SetClipTimes([(0.0, 0.0), (last, last)] if last > 0 else [(0.0, 0.0)])
            clips.SetClipManifestAssetPath(Sdf.AssetPath(rel + _MANIFEST))
        del stage

    def close(self) -> None:
        """Finish the file(s) and move them into place atomically.

        Raises
        ------
        InputError
            If fewer than ``n_frames`` frames were written (call :meth:`abort`
            to discard), or a file could not be written.
        """
        if self._closed:
            raise InputError("close: the writer is already closed or aborted")
        if self.frames_written != self.n_frames:
            raise InputError(f"close: only {self.frames_written} of {self.n_frames} frames were written")
        _, Sdf, _, _, _ = _pxr()
        image = write_texture_beside(self.path, self.mesh)  # before the file that names it
        self._image_name = None if image is None else image.name
        if not self.use_clips:
            self._author_top(self._layer)
            with atomic_path(self.path) as tmp:
                if not self._layer.Export(str(tmp)):
                    raise InputError("could not write the USD file", path=str(self.path))
            self._layer = None
            self._remove_stale_clips()
            self._closed = True
            return

        for index in sorted(self._clips):
            self._save_clip(index)
        staging = Path(str(self._staging))
        manifest = Sdf.Layer.CreateNew(str(staging / _MANIFEST))
        self._declare_animated(manifest)
        if not manifest.Save():
            raise InputError("could not save the USD clip manifest", path=str(staging / _MANIFEST))
        del manifest

        old = None
        if self.clips_dir.exists():
            old = self.path.with_name(f".{self.clips_dir.name}.old-{secrets.token_hex(4)}")
            os.replace(self.clips_dir, old)
        os.replace(staging, self.clips_dir)
        self._staging = None
        try:
            with atomic_path(self.path) as tmp:
                # Authored in place beside the clips so their relative paths resolve.
                top = Sdf.Layer.CreateNew(str(tmp))
                self._author_top(top)
                saved = top.Save()
                del top
                if not saved:
                    raise InputError("could not write the USD file", path=str(self.path))
        except BaseException:
            # Put the previous clips back so an older file still finds its clips.
            shutil.rmtree(self.clips_dir, ignore_errors=True)
            if old is not None:
                os.replace(old, self.clips_dir)
            self._closed = True
            raise
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        self._closed = True

    @staticmethod
    def _is_our_clips_dir(d: Path) -> bool:
        """True if ``d`` is a folder holding only clip files and a manifest as this writer names them."""
        return d.is_dir() and all(_OUR_CLIP_FILE.match(p.name) and p.is_file() for p in d.iterdir())

    def _remove_stale_clips(self) -> None:
        """Remove a ``<stem>_clips/`` folder of an earlier clip-mode export of this file."""
        if self._is_our_clips_dir(self.clips_dir):
            shutil.rmtree(self.clips_dir, ignore_errors=True)

    def abort(self) -> None:
        """Discard everything written so far; ``path`` and any earlier file there are untouched."""
        self._clips.clear()
        self._layer = None
        if self._staging is not None:
            shutil.rmtree(self._staging, ignore_errors=True)
            self._staging = None
        self._closed = True

    def __enter__(self) -> "UsdPerformanceWriter":
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is not None:
            self.abort()
        elif not self._closed:
            self.close()
