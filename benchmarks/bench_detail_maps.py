"""Time the detail maps: the UV raster's set-up and the per-frame displacement and normal maps.

    PYTHONPATH=src python benchmarks/bench_detail_maps.py [--vertices 150000 600000] [--sizes 1024 2048]

A wavy grid with two UV islands (a seam down the middle), the detail region half of it.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def wavy_grid(n_vertices: int):
    k = int(round(np.sqrt(n_vertices)))
    x = np.linspace(0, 200.0, k)
    X, Y = np.meshgrid(x, x)
    Z = 5 * np.sin(X / 20) * np.cos(Y / 25)
    V = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    idx = np.arange(k * k).reshape(k, k)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    F = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    right = V[F].mean(axis=1)[:, 0] > 100
    UV_left = np.stack([0.02 + 0.46 * V[:, 0] / 100, 0.02 + 0.96 * V[:, 1] / 200], 1)
    UV_right = np.stack([0.52 + 0.46 * (V[:, 0] - 100) / 100, 0.02 + 0.96 * V[:, 1] / 200], 1)
    uv_triangles = np.where(right[:, None], F + V.shape[0], F)
    return V, F, np.vstack([UV_left, UV_right]), uv_triangles


def main() -> None:
    from facecap.sfs.detail_maps import DetailMaps

    parser = argparse.ArgumentParser()
    parser.add_argument("--vertices", type=int, nargs="+", default=[150_000, 600_000])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1024, 2048])
    parser.add_argument("--frames", type=int, default=3)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    for n in args.vertices:
        V, F, UV, uv_triangles = wavy_grid(n)
        region = np.flatnonzero((V[:, 0] > 40) & (V[:, 0] < 160))
        for size in args.sizes:
            t = time.perf_counter()
            maps = DetailMaps(UV, uv_triangles, F, region, size)
            setup = time.perf_counter() - t
            times_d, times_n = [], []
            for _ in range(args.frames):
                h = rng.normal(scale=0.05, size=region.size)
                t = time.perf_counter()
                maps.displacement(h)
                times_d.append(time.perf_counter() - t)
                t = time.perf_counter()
                maps.normal_map(V, h)
                times_n.append(time.perf_counter() - t)
            print(f"{V.shape[0]:>7} vertices {F.shape[0]:>7} triangles, region {region.size:>6}, {size}^2: "
                  f"set-up {setup:.2f} s, displacement {1000 * min(times_d):.0f} ms, "
                  f"normal map {1000 * min(times_n):.0f} ms per frame")


if __name__ == "__main__":
    main()
