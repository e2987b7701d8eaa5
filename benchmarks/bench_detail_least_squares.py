"""The detail solve against the naive route the issue names: one ``scipy.optimize.least_squares`` per frame.

On one frame of a generated take (the region ``facecap detail`` chose, its footage, lights and cameras), the
same objective (the image term through each camera's blur, eq. 6's one-ring, the anchor; one frame, so no
temporal term) is solved twice: by :func:`facecap.sfs.solve_heights` (Gauss-Newton, compiled matrix-free CG)
and by ``least_squares`` (trust-region reflective, LSMR, a sparse finite-difference Jacobian from the
problem's pattern). Both start at zero; the table gives the seconds and the objective each reaches.

    python benchmarks/bench_detail_least_squares.py [--case benchmarks/_work/detail/held2] [--frame 12]

Run ``benchmarks/bench_detail.py --cases held2`` first (it makes the case, the layer below and the detail
result whose region is reused).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp


def main() -> None:
    from scipy.optimize import least_squares

    from facecap.cameras import read_camera_file, read_light_file
    from facecap.sfs import DetailFrameStage, HeightWeights, shade_frame, solve_heights
    from facecap.sfs.solve_heights import _one_ring_average

    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--case", default="benchmarks/_work/detail/held2")
    parser.add_argument("--frame", type=int, default=12)
    args = parser.parse_args()
    case = Path(args.case)
    animate, detail = case.parent / f"{case.name}_animate", case.parent / f"{case.name}_detail"
    setup = read_camera_file(case / "cameras.json")
    lights = read_light_file(case / "lights.json")
    truth = np.load(case / "truth.npz")
    region = np.load(detail / "detail_region.npy")
    reflectance = json.loads((detail / "detail.json").read_text())["reflectance"]
    albedo, k_s, alpha = reflectance["albedo_median"], reflectance["k_s_median"], reflectance["alpha_median"]
    stage = DetailFrameStage(str(animate.resolve()), setup.cameras, [str(case / "cam_left"), str(case / "cam_right")],
                             lights, truth["video_mocap_frames"].astype(float), region, np.full(region.size, albedo),
                             k_s, alpha, "srgb")
    frame, _ = stage.observe(args.frame)
    weights = HeightWeights(temporal=0.0, sparsity_mm=None, bulge=1.0)  # quadratic, as least_squares needs
    r = region.size

    t = time.perf_counter()
    ours = solve_heights([frame], albedo=albedo, k_s=k_s, alpha=alpha, ambient=lights.ambient, weights=weights)
    ours_s = time.perf_counter() - t

    base, _, _ = shade_frame(frame, np.zeros(r), albedo, k_s, alpha, lights.ambient)
    floor = 0.05 * float(np.median(base[frame.weight > 0]))
    scale = np.maximum(base, floor)
    root_w = np.sqrt(frame.weight)
    S = _one_ring_average(frame.gradient) * np.sqrt(weights.spatial)

    def residuals(h: np.ndarray) -> np.ndarray:
        syn, _, _ = shade_frame(frame, h, albedo, k_s, alpha, lights.ambient)
        seen = np.stack([base[c] + frame.blur[c] @ (syn[c] - base[c]) for c in range(syn.shape[0])])
        return np.concatenate([(root_w * (seen - frame.intensity) / scale).ravel(), S @ h,
                               np.sqrt(weights.anchor) * h])

    G = frame.gradient
    ring = ((abs(G.x) + abs(G.y) + abs(G.z)) != 0).astype(np.float64)
    image = sp.vstack([(blur != 0).astype(np.float64) @ ring for blur in frame.blur])
    pattern = sp.vstack([image, (S != 0).astype(np.float64), sp.identity(r)]).tocsr()
    t = time.perf_counter()
    naive = least_squares(residuals, np.zeros(r), jac_sparsity=pattern, method="trf", tr_solver="lsmr",
                          x_scale=1.0, max_nfev=20, verbose=0)
    naive_s = time.perf_counter() - t
    cost_ours = 0.5 * float(np.sum(residuals(ours.heights[0]) ** 2))
    print(json.dumps({"case": str(case), "video_frame": args.frame, "samples": int(r),
                      "solve_heights_s": round(ours_s, 2), "solve_heights_cost": cost_ours,
                      "least_squares_s": round(naive_s, 2), "least_squares_cost": float(naive.cost),
                      "least_squares_evaluations": int(naive.nfev), "least_squares_status": int(naive.status),
                      "ratio": round(naive_s / ours_s, 1)}, indent=1))


if __name__ == "__main__":
    main()
