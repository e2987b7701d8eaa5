"""Speed of choosing the frames to scan (Huang et al. 2011, Alg. 1) and of batched NNLS weights.

One run prints a ``RESULT {json}`` line and markdown tables::

    python benchmarks/bench_select_scan_frames.py [--frames 1500] [--markers 100] [--repeats 3]
        [--baseline-frames 200] [--save results.json]

What is measured (wall time, median of ``--repeats``; the take's generation is not timed):

selection
    :func:`facecap.blendshapes.select_scan_frames` at the default tolerance
    (0.3 % of the bounding-box diagonal) on ``generate_performance(n_frames,
    n_markers, rate=60)`` with the head band off, no head motion and no gaps
    (what a caller has after ``fill_gaps`` and ``stabilize_head``), 0.2 mm noise.
    Also one run forced to 30 frames (``tolerance=0, max_frames=30``), the
    paper's largest scan count, to show the cost per frame as the set grows.
baseline
    Algorithm 1 as written: for every candidate, ``scipy.optimize.nnls`` for
    every frame. Too slow for the whole take, so both it and the fast search run
    on ``--baseline-frames`` frames spread evenly over the take (all markers),
    for as many steps as the fast search takes there; the ratio is of those two,
    measured in the same run, and the chosen frames must agree.
nnls
    :func:`facecap.blendshapes.nnls_weights` for all frames against 30 bases
    (30 frames of the take), against a loop of ``scipy.optimize.nnls`` over the
    frames; the largest residual difference is reported.

Every figure comes with the CPU time other processes took meanwhile
(``other_cores``, from ``/proc/stat``), since the benchmark machine is shared.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import nnls

from facecap.blendshapes import nnls_weights, select_scan_frames
from facecap.synth import generate_performance

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _load import Window  # noqa: E402


def timed(fn: Callable[[], Any], repeats: int) -> tuple[Any, dict[str, Any]]:
    """Run ``fn`` ``repeats`` times; the last result and the median wall time with its load."""
    runs = []
    out = None
    for _ in range(repeats):
        with Window() as w:
            out = fn()
        runs.append(w)
    order = sorted(range(repeats), key=lambda i: runs[i].seconds)
    mid = runs[order[len(order) // 2]]
    return out, {
        "median_s": statistics.median(r.seconds for r in runs),
        "all_s": [round(r.seconds, 4) for r in runs],
        "cpu_s": round(mid.my_cores * mid.seconds, 3),
        "my_cores": round(mid.my_cores, 2),
        "other_cores": round(mid.other_cores, 2),
    }


def brute_force(positions: np.ndarray, n_steps: int) -> tuple[list[int], list[float]]:
    """Algorithm 1 as written (every candidate, scipy NNLS for every frame); RMS error per step, mm."""
    T, M, _ = positions.shape
    X = positions.reshape(T, -1).T
    chosen: list[int] = []
    errors: list[float] = []
    for _ in range(n_steps):
        best, best_j = np.inf, -1
        for j in range(T):
            if j in chosen:
                continue
            B = X[:, chosen + [j]]
            total = sum(nnls(B, X[:, t], maxiter=100 * B.shape[1])[1] ** 2 for t in range(T))
            if total < best:
                best, best_j = total, j
        chosen.append(best_j)
        errors.append(float(np.sqrt(best / (T * M))))
    return chosen, errors


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=1500)
    ap.add_argument("--markers", type=int, default=100)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--baseline-frames", type=int, default=200)
    ap.add_argument("--bases", type=int, default=30)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--save", default=None)
    args = ap.parse_args()

    case = generate_performance(
        n_frames=args.frames, n_markers=args.markers, rate=60.0, headband_markers=0, head_rotation_deg=0.0,
        head_translation_mm=0.0, gap_fraction=0.0, seed=args.seed,
    )
    P = case.markers.positions
    T, M, _ = P.shape
    result: dict[str, Any] = {
        "take": {"frames": T, "markers": M, "rate_hz": 60.0, "noise_mm": 0.2},
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "numpy": np.__version__,
                    "blas_threads_env": os.environ.get("OPENBLAS_NUM_THREADS")},
    }

    # ---- selection on the whole take, default tolerance
    plan, t_sel = timed(lambda: select_scan_frames(P, rate=60.0), args.repeats)
    result["selection"] = {
        **t_sel, "frames_chosen": plan.n_frames, "frames": plan.frames.tolist(),
        "error_after_each_mm": [round(e, 4) for e in plan.error_after_each.tolist()],
        "tolerance_mm": round(plan.tolerance_mm, 4), "diagonal_mm": round(plan.diagonal_mm, 2),
        "converged": plan.converged,
    }
    plan30, t30 = timed(lambda: select_scan_frames(P, tolerance=0.0, max_frames=30), 1)
    result["selection_30"] = {**t30, "frames_chosen": plan30.n_frames,
                              "final_error_mm": round(float(plan30.error_after_each[-1]), 4)}

    # ---- brute-force baseline on a subset, same number of steps
    sub = P[np.linspace(0, T - 1, args.baseline_frames).round().astype(int)]
    plan_sub, t_fast = timed(lambda: select_scan_frames(sub), args.repeats)
    steps = plan_sub.n_frames
    with Window() as w:
        bf_frames, bf_errors = brute_force(sub, steps)
    result["baseline"] = {
        "frames": sub.shape[0], "markers": M, "steps": steps,
        "fast": t_fast,
        "brute_force": {"seconds": w.seconds, "my_cores": round(w.my_cores, 2), "other_cores": round(w.other_cores, 2)},
        "speedup": w.seconds / t_fast["median_s"],
        "same_frames": bf_frames == plan_sub.frames.tolist(),
        "max_rel_error_difference": float(np.max(np.abs(np.array(bf_errors) - plan_sub.error_after_each)
                                                 / np.array(bf_errors))),
    }

    # ---- nnls_weights: every frame against K bases
    X = P.reshape(T, -1).T
    bases = X[:, np.linspace(0, T - 1, args.bases).round().astype(int)]
    (_, res), t_nnls = timed(lambda: nnls_weights(bases, X), args.repeats)
    with Window() as w:
        ref = np.array([nnls(bases, X[:, t], maxiter=100 * args.bases)[1] for t in range(T)])
    result["nnls"] = {
        "targets": T, "bases": args.bases, "dim": X.shape[0], **t_nnls,
        "scipy_loop_s": w.seconds, "scipy_other_cores": round(w.other_cores, 2),
        "speedup": w.seconds / t_nnls["median_s"],
        "max_residual_difference_mm": float(np.max(np.abs(res - ref))),
    }

    print("RESULT " + json.dumps(result))
    s, b, n = result["selection"], result["baseline"], result["nnls"]
    print()
    print("| what | size | wall (median) | CPU | other cores busy | result |")
    print("|---|---|---|---|---|---|")
    print(f"| select_scan_frames, tolerance 0.3% | {T} frames x {M} markers | {s['median_s']:.2f} s "
          f"| {s['cpu_s']:.2f} s | {s['other_cores']:.2f} | {s['frames_chosen']} frames, "
          f"{s['error_after_each_mm'][-1]:.3f} mm RMS (goal {s['tolerance_mm']:.3f}) |")
    r30 = result["selection_30"]
    print(f"| select_scan_frames, 30 frames | {T} x {M} | {r30['median_s']:.2f} s | {r30['cpu_s']:.2f} s "
          f"| {r30['other_cores']:.2f} | {r30['final_error_mm']:.3f} mm RMS |")
    print(f"| select_scan_frames | {b['frames']} x {M} | {b['fast']['median_s']:.3f} s | {b['fast']['cpu_s']:.3f} s "
          f"| {b['fast']['other_cores']:.2f} | {b['steps']} frames |")
    print(f"| brute-force Alg. 1 (scipy nnls) | {b['frames']} x {M} | {b['brute_force']['seconds']:.1f} s | "
          f"| {b['brute_force']['other_cores']:.2f} | same frames: {b['same_frames']}; {b['speedup']:.0f}x slower |")
    print(f"| nnls_weights | {n['targets']} targets x {n['bases']} bases (D={n['dim']}) | {n['median_s'] * 1e3:.0f} ms "
          f"| {n['cpu_s'] * 1e3:.0f} ms | {n['other_cores']:.2f} "
          f"| max abs(r - r_scipy) {n['max_residual_difference_mm']:.1e} mm |")
    print(f"| scipy.optimize.nnls loop | same | {n['scipy_loop_s']:.2f} s | | {n['scipy_other_cores']:.2f} "
          f"| {n['speedup']:.1f}x slower |")
    if args.save:
        with open(args.save, "w") as f:
            json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
