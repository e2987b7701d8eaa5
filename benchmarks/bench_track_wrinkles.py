"""Wrinkle tracking (issue 10 item 3) on generated footage: distance of the tracked valleys to the truth, and speed.

    python benchmarks/bench_track_wrinkles.py CASE_DIR [CASE_DIR ...] [--weighting darkness|uniform] [--binary-masks]

CASE_DIR is a ``facecap synth --footage`` folder. For each camera and video frame the tracked
curves (caps trimmed) are compared with the truth valley curves (``truth.npz`` ``curve_points``,
scan frame, carried to the mocap frame by ``mocap_from_scan @ head_pose[t]``) projected through
the camera: the mean of the distances from tracked points to the truth polyline and from truth
points to the tracked polyline, each over the parameter range the two curves share.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np


def polyline_distance(points: np.ndarray, polyline: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance of each point to a polyline, and whether its nearest point is interior (not an end)."""
    A, B = polyline[:-1], polyline[1:]
    AB = B - A
    t = np.einsum("pkd,kd->pk", points[:, None] - A[None], AB) / np.maximum(np.einsum("kd,kd->k", AB, AB), 1e-12)
    t = np.clip(t, 0.0, 1.0)
    nearest = A[None] + t[..., None] * AB[None]
    d = np.linalg.norm(points[:, None] - nearest, axis=2)
    k = d.argmin(axis=1)
    tk = t[np.arange(len(points)), k]
    interior = ~(((k == 0) & (tk <= 0.0)) | ((k == len(A) - 1) & (tk >= 1.0)))
    return d[np.arange(len(points)), k], interior


def curve_error(tracked: np.ndarray, truth: np.ndarray) -> float:
    d1, i1 = polyline_distance(tracked, truth)
    d2, i2 = polyline_distance(truth, tracked)
    both = np.concatenate([d1[i1], d2[i2]])
    return float(both.mean()) if both.size else float("nan")


def evaluate(case: Path, weighting: str, binary_masks: bool = False) -> dict:
    from facecap.cameras import open_footage, read_camera_file, read_image
    from facecap.wrinkles import WrinkleTracker, train_paint_classifier

    truth = np.load(case / "truth.npz")
    setup = read_camera_file(case / "cameras.json")
    points = truth["curve_points"]
    M = truth["mocap_from_scan"] @ truth["head_pose"]
    paint = truth["paint_index"]
    video_rate = float(truth["video_rate"]) if "video_rate" in truth else 12.5
    step = int(round(float(truth["rate"]) / video_rate))
    out = {}
    for name in setup.names:
        camera = setup.camera(name)
        footage = open_footage(case / name)
        mask = read_image(case / f"mask_{name}.png")
        if binary_masks:  # one mask for every paint: the classifier separates the colours itself
            mask = mask > 0
        t0 = time.perf_counter()
        classifier = train_paint_classifier(footage.frame(0), mask)
        train_s = time.perf_counter() - t0
        tracker = WrinkleTracker(classifier, camera=name, weighting=weighting)
        errors, times, matched, elongated = [], [], {}, []
        for j, image in enumerate(footage):
            t = j * step
            t0 = time.perf_counter()
            wrinkles = tracker.track(image)
            times.append(time.perf_counter() - t0)
            X = points[t] @ M[t][:3, :3].T + M[t][:3, 3]
            frame_errors = {}
            for w in wrinkles:
                curve = w.curve(64)
                if w.wrinkle not in matched:  # the truth curve of its paint nearest in frame 0
                    # (separated colours are numbered by their own order: then any curve may match)
                    candidates = np.arange(len(paint)) if binary_masks else np.flatnonzero(paint == w.color)
                    # whole curves both ways (ends included): a neighbour that overlaps only in part scores badly
                    scores = [np.mean(polyline_distance(camera.project(X[c]).pixels, curve)[0])
                              + np.mean(polyline_distance(curve, camera.project(X[c]).pixels)[0]) for c in candidates]
                    matched[w.wrinkle] = int(candidates[int(np.nanargmin(scores))])
                c = matched[w.wrinkle]
                frame_errors[w.wrinkle] = curve_error(curve, camera.project(X[c]).pixels)
                if w.spline.elongation >= 3.0:
                    elongated.append(frame_errors[w.wrinkle])
            errors.append(frame_errors)
        flat = np.array([v for e in errors for v in e.values()])
        out[name] = {
            "mean_px": float(np.nanmean(flat)),
            "mean_px_elongation_3_or_more": float(np.nanmean(elongated)),
            "share_elongation_3_or_more": len(elongated) / flat.size, "median_px": float(np.nanmedian(flat)), "max_px": float(np.nanmax(flat)),
            "per_wrinkle_mean_px": {str(truth["curve_names"][c]): float(np.nanmean([e[i] for e in errors if i in e]))
                                    for i, c in sorted(matched.items())},
            "wrinkles": tracker.n_wrinkles, "frames": len(errors),
            "train_s": train_s, "track_s_per_frame": float(np.median(times)),
        }
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("cases", nargs="+", type=Path)
    parser.add_argument("--weighting", default="uniform", choices=["uniform", "darkness"])
    parser.add_argument("--binary-masks", action="store_true", help="train from one binary mask per camera")
    args = parser.parse_args()
    for case in args.cases:
        print(case, json.dumps(evaluate(case, args.weighting, args.binary_masks), indent=1))


if __name__ == "__main__":
    main()
