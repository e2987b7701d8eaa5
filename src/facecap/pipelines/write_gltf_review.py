"""A result as one glTF review file: a decimated mesh, its principal morph targets, their animation.

The glTF export of a result (``--export gltf``, ``facecap export --format
gltf``) is what a browser or a DCC tool can play without the full frames:

1. the review mesh: at most ``max_vertices`` of the scan's own vertices
   (:func:`facecap.mesh.review_mesh`: vertex clustering, so every kept vertex
   moves exactly as in the result);
2. the morph targets: the take's motion at those vertices as its first
   principal components (:mod:`facecap.deform.principal_targets`): exact when
   the rig has at most ``max_targets`` elements (the blend's bases), otherwise
   the best ``max_targets`` in the least-squares sense, with the error they
   leave computed exactly and returned (it goes into ``performance.json``'s
   ``exports_report`` and the file's ``asset.extras``);
3. the weights are moved into [0, 1] (:mod:`facecap.io.weight_ranges`), the
   range Blender plays without clamping; the base mesh is the shape at
   all-zero weights, the rest shape at ``asset.extras.facecap.rest_weights``;
4. :func:`facecap.io.write_gltf` writes them in metres with the weights
   animation at the take's rate, the markers as animated nodes and, for a
   stabilised result, the head motion as the animation of a root node.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from ..io.read_result import Result
from ..io.weight_ranges import to_unit_range

__all__ = ["write_gltf_review"]


def write_gltf_review(
    path: str | os.PathLike[str],
    result: Result,
    *,
    max_targets: int = 64,
    max_vertices: int = 100_000,
    compress: bool = False,
    batch_frames: int = 64,
    progress: bool = False,
) -> dict[str, Any]:
    """Write ``result`` as a ``.glb`` review file; returns what was written and the error it leaves.

    Parameters
    ----------
    path : str or path-like
        The ``.glb`` to write (atomically).
    result : Result
        An opened result folder (:func:`facecap.io.read_result`).
    max_targets : int, default 64
    max_vertices : int, default 100,000
    compress : bool, default False
        ``EXT_meshopt_compression``.
    batch_frames : int, default 64
        Frames per block when the result has no rig (streamed randomized SVD).
    progress : bool, default False

    Returns
    -------
    dict
        ``review_vertices``, ``decimated`` (bool), ``n_targets``, ``error``
        (mm: ``max_mm``, ``rms_mm``, ... over the review mesh and the take),
        ``gpu_morph_bytes``, ``bytes``.
    """
    from ..deform.principal_targets import principal_targets, principal_targets_from_rig
    from ..mesh.review_mesh import review_mesh
    from ..io.write_gltf import write_gltf

    review = review_mesh(result.mesh, max_vertices=max_vertices)
    subset = review.vertex_subset
    to_mm = np.float32(result.mm_per_unit)
    rig = result.rig
    if rig is not None:
        basis, coefficients = rig.in_mm(subset)
        found = principal_targets_from_rig(basis, coefficients, max_targets=max_targets, progress=progress)
        base = review.mesh.with_vertices(rig.rest[subset].astype(np.float64) * float(to_mm))
    else:
        def blocks() -> Any:
            for start, block in result.blocks(batch_frames):
                yield start, block * to_mm
        found = principal_targets(blocks, result.mesh.vertices, n_frames=result.n_frames, vertex_subset=subset,
                                  max_targets=max_targets, progress=progress)
        base = review.mesh
    # weights in [0, 1]: Blender's glTF importer widens a shape key's range by the first keyframe only
    unit = to_unit_range(found.targets, found.weights, overwrite_targets=True)  # found is ours: no copy
    base = base.with_vertices(base.vertices + unit.base_offset)
    markers = None if result.markers is None else result.markers * to_mm
    head_motion = None
    if result.head_motion is not None:
        head_motion = result.head_motion.copy()
        head_motion[:, :3, 3] *= float(to_mm)
    error = {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in found.error.items()}
    info = write_gltf(
        path, base, targets=unit.targets, weights=unit.weights, rate=result.rate,
        markers=markers, marker_labels=list(result.marker_labels) or None, head_motion=head_motion,
        compress=compress, progress=progress,
        extras={"facecap": {"result": str(result.path.name), "method": result.info.get("method"),
                            "review_vertices": int(subset.size), "scan_vertices": result.n_vertices,
                            "rest_weights": unit.rest_weights.tolist(),
                            "principal_component_error_mm": error}},
    )
    return {
        "review_vertices": int(subset.size),
        "decimated": bool(subset.size < result.n_vertices),
        "n_targets": int(info["n_targets"]),
        "error": error,
        "gpu_morph_bytes": int(info["gpu_morph_bytes"]),
        "bytes": int(info["bytes"]),
    }
