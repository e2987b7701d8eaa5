"""Ray casting speed: every pixel of a 1384x1038 camera against the benchmark faces, and vertex visibility.

For each mesh (the bundled ICT sample, ``_meshes.bench_mesh('100k')`` and ``'700k'``): the Embree build
(:class:`facecap.cameras.RayCaster`), the pixel rays (``Camera.pixel_rays``, OpenCV's undistortion), one
full-frame cast (Embree plus the float64 refinement), the same with ``robust=True`` (four casts), Embree's
own call alone (``embreex`` on the same float32 rays, the baseline), and ``visible_vertices``.
Each timing is the best of ``--repeat`` runs.

    python benchmarks/bench_ray_cast.py [--repeat 3] [--cases sample,100k,700k]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def _best(fn, repeat: int) -> tuple[float, object]:
    best, out = np.inf, None
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - start)
    return best, out


def _mesh(case: str) -> tuple[np.ndarray, np.ndarray]:
    if case == "sample":
        from facecap.io.ict_sample import load_ict_sample

        mesh = load_ict_sample().mesh
        return mesh.vertices, mesh.faces
    from _meshes import bench_mesh

    mesh = bench_mesh(case)
    return mesh.V, mesh.F


def run(case: str, repeat: int) -> dict[str, float | int | str]:
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    from facecap.cameras import Camera, RayCaster

    V, F = _mesh(case)
    centre = (V.min(axis=0) + V.max(axis=0)) / 2
    cam = Camera.look_at("front", centre + [120.0, 30.0, 650.0], centre + [0.0, 0.0, 40.0], focal_px=2600.0,
                         width=1384, height=1038, distortion=[-0.1, 0.05, 1e-3, -5e-4, 0.01])
    build_s, caster = _best(lambda: RayCaster(V, F), repeat)
    pixels = cam.pixel_grid()
    n_rays = pixels.shape[0] * pixels.shape[1]
    rays_s, rays = _best(lambda: cam.pixel_rays(pixels), repeat)
    cast_s, hits = _best(lambda: caster.cast(rays.origins, rays.directions), repeat)
    robust_s, _ = _best(lambda: caster.cast(rays.origins, rays.directions, robust=True), repeat)
    scene = rtcore_scene.EmbreeScene(robust=True)
    TriangleMesh(scene=scene, vertices=(V - centre).astype(np.float32), indices=F.astype(np.int32))
    O = (rays.origins - centre).reshape(-1, 3).astype(np.float32)
    D = rays.directions.reshape(-1, 3).astype(np.float32)
    scene.run(O[:1], D[:1])
    embree_s, _ = _best(lambda: scene.run(O, D, output=1), repeat)
    visible_s, visible = _best(lambda: caster.visible_vertices(cam), repeat)
    return {
        "case": case, "vertices": int(V.shape[0]), "triangles": int(F.shape[0]), "rays": n_rays,
        "hits": int(hits.hit.sum()), "build_s": round(build_s, 3), "pixel_rays_s": round(rays_s, 3),
        "cast_s": round(cast_s, 3), "cast_rays_per_s": round(n_rays / cast_s),
        "cast_robust_s": round(robust_s, 3), "embree_only_s": round(embree_s, 3),
        "embree_rays_per_s": round(n_rays / embree_s), "visible_vertices_s": round(visible_s, 3),
        "visible": int(visible.sum()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--cases", default="sample,100k,700k")
    args = parser.parse_args()
    for case in args.cases.split(","):
        print(json.dumps(run(case, args.repeat)), flush=True)


if __name__ == "__main__":
    main()
