"""Where the detail layer loses the lines: the layer below's shape against where each sample is read (issue 30).

Stage by stage against the generator's truth. ``capture_detail`` runs with its defaults on the part of the face
around the lines (every vertex within ``--grow`` mm of one whose true detail ever exceeds 0.03 mm), with two
things swapped for the truth in turn:

- the *geometry*: the layer below (``animate``'s result, the default) or the true surface without the
  expression-driven detail (``L``, carried into the mocap frame by the true head pose);
- the *placement*: where each sample is read in each image. ``flow``: the default (the layer's projection
  refined by :func:`~facecap.sfs.follow_skin`); ``none``: the geometry's projection (``follow_skin`` off);
  ``true``: the projection of the sample's own material point on the true surface ``G`` (the skin point whose
  detail the vertex-by-vertex metric asks for); ``true+0.3``, ``true+0.7``: that, moved by 0.3 or 0.7 px in a
  random direction per frame and camera (a rigid misplacement).

For each variant: the vertex-by-vertex ratio on the region's lines (``mean |h - h_true|`` over ``mean
|h_true|`` where ``|h_true| > 0.03`` mm, ``h`` the added height along the layer's normal: the bar's metric
restricted to the region), the correlation of ``h`` with the truth there, and the mean ``|h|`` away from the
lines. Beside them, the flow's placement error against the true pixel (camera 0: median distance, the median
error vector, and the spread about it).

    python benchmarks/bench_detail_placement.py --case tuned0 [--work benchmarks/_work/detail] [--grow 1.5]

The case folders are :mod:`bench_detail`'s (run it first, or let this script make them).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

VARIANTS = [("layer", "flow"), ("layer", "none"), ("layer", "true"), ("truth", "true"), ("truth", "true+0.3"),
            ("truth", "true+0.7"), ("truth", "flow")]


def _stage_class(truth: dict, geometry: str, placement: str, reading: dict):  # type: ignore[no-untyped-def]
    """A :class:`~facecap.sfs.DetailFrameStage` whose geometry and placement are the truth's where asked (the
    placement through ``reading['pixels']``, which :func:`_run`'s reader uses)."""
    from facecap.sfs.detail_frame_stage import DetailFrameStage

    pose = truth["mocap_from_scan"] @ truth["head_pose"]

    def world(t: int, V: np.ndarray) -> np.ndarray:
        return V.astype(np.float64) @ pose[t][:3, :3].T + pose[t][:3, 3]

    class Swapped(DetailFrameStage):
        def _mocap_frame(self, video_frame: int) -> int:
            return int(round(float(self.mocap_frames[video_frame])))

        if geometry == "truth":
            def large_scale(self, video_frame):  # type: ignore[no-untyped-def]
                return truth["without_detail"][self._mocap_frame(video_frame)].astype(np.float64)

            def mocap_vertices(self, video_frame):  # type: ignore[no-untyped-def]
                t = self._mocap_frame(video_frame)
                L = truth["without_detail"][t].astype(np.float64)
                return L, world(t, L)

        def observe(self, video_frame, **kw):  # type: ignore[no-untyped-def]
            if placement.startswith("true"):  # every frame, the rest frame too (where the albedo is measured)
                t = self._mocap_frame(video_frame)
                X = world(t, truth["vertices"][t][self.region])
                shift = float(placement[5:] or 0.0)
                rng = np.random.default_rng([t, 7])
                pixels = []
                for camera in self.cameras:
                    angle = rng.uniform(0.0, 2.0 * np.pi)
                    pixels.append(camera.project(X).pixels + shift * np.array([np.cos(angle), np.sin(angle)]))
                reading["pixels"] = pixels
            return super().observe(video_frame, **kw)

    return Swapped


def _run(folder: Path, animate: Path, truth: dict, region: np.ndarray, geometry: str, placement: str) -> dict:
    import facecap.sfs.detail_frame_stage as module
    from facecap.cameras import read_camera_file, read_light_file
    from facecap.io.read_result import read_result
    from facecap.mesh.vertex_normals import vertex_normals
    from facecap.pipelines import capture_detail

    setup = read_camera_file(folder / "cameras.json")
    original, original_reader = module.DetailFrameStage, module.sample_footage
    reading: dict = {}
    module.DetailFrameStage = _stage_class(truth, geometry, placement, reading)  # capture_detail imports it then
    if placement.startswith("true"):
        def read_at_truth(images, cameras, points, normals, visible, pixels=None):  # type: ignore[no-untyped-def]
            return original_reader(images, cameras, points, normals, visible, pixels=reading["pixels"])
        module.sample_footage = read_at_truth
    options = {"follow_skin": placement == "flow"}
    try:
        with tempfile.TemporaryDirectory() as work, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = Path(work) / "detail"
            t = time.perf_counter()
            capture_detail(animate, setup.cameras, [folder / "cam_left", folder / "cam_right"],
                           read_light_file(folder / "lights.json"), out, video_rate_hz=setup.video_rate_hz,
                           regions=region, map_size=0, scheduler="synchronous", options=options, progress=False)
            seconds = time.perf_counter() - t
            base, detail = read_result(animate), read_result(out)
            solved = np.load(out / "detail_region.npy")
            lines = truth["detail_mask"][solved]
            error = size = 0.0
            found, true, away = [], [], []
            for t in truth["video_mocap_frames"]:
                A = base.frames(int(t), int(t) + 1)[0].astype(np.float64)
                D = detail.frames(int(t), int(t) + 1)[0].astype(np.float64)
                h = np.sum((D - A)[solved] * vertex_normals(A, base.mesh.faces, solved), axis=1)
                h_true = truth["detail_height"][t][solved].astype(np.float64)
                on = np.abs(h_true) > 0.03
                error += float(np.abs(h - h_true)[on].sum())
                size += float(np.abs(h_true)[on].sum())
                found.append(h[on])
                true.append(h_true[on])
                away.append(float(np.abs(h[~lines]).mean()))
    finally:
        module.DetailFrameStage, module.sample_footage = original, original_reader
    found_all, true_all = np.concatenate(found), np.concatenate(true)
    return {"geometry": geometry, "placement": placement, "ratio": error / max(size, 1e-12),
            "correlation": float(np.corrcoef(found_all, true_all)[0, 1]), "away_mm": float(np.mean(away)),
            "samples": int(solved.size), "seconds": seconds}


def _flow_error(folder: Path, animate: Path, truth: dict, region: np.ndarray) -> list[dict]:
    """The default flow's placement against the true pixel of each sample's material point (camera 0)."""
    from facecap.cameras import read_camera_file, read_light_file
    from facecap.sfs.detail_frame_stage import DetailFrameStage

    setup = read_camera_file(folder / "cameras.json")
    video = truth["video_mocap_frames"]
    samples = np.flatnonzero(region)
    stage = DetailFrameStage(str(animate), setup.cameras, [str(folder / "cam_left"), str(folder / "cam_right")],
                             read_light_file(folder / "lights.json"), video.astype(float), samples,
                             np.ones(samples.size), 0.0, 1.0, "srgb", {})
    pose = truth["mocap_from_scan"] @ truth["head_pose"]
    camera = setup.cameras[0]
    rows = []
    for j in np.linspace(video.size // 2, video.size - 1, 3).astype(int):
        t = int(video[j])
        X = truth["vertices"][t][samples].astype(np.float64) @ pose[t][:3, :3].T + pose[t][:3, 3]
        target = camera.project(X).pixels
        _, Y = stage.mocap_vertices(int(j))
        layer = camera.project(Y[samples]).pixels
        pixels, _ = stage._followed_pixels([stage.image(c, int(j)) for c in range(2)], Y[samples])
        row = {"video_frame": int(j)}
        for name, at in (("layer", layer), ("flow", pixels[0])):
            e = at - target
            bias = np.median(e, axis=0)
            row[name] = {"median_px": float(np.median(np.linalg.norm(e, axis=1))), "bias_px": bias.round(2).tolist(),
                         "spread_px": float(np.median(np.linalg.norm(e - bias, axis=1)))}
        rows.append(row)
    return rows


def main() -> None:
    from scipy.spatial import cKDTree

    from bench_detail import _case
    from facecap.io.read_result import read_result

    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--case", default="tuned0")
    parser.add_argument("--work", default="benchmarks/_work/detail")
    parser.add_argument("--frames", type=int, default=41)
    parser.add_argument("--grow", type=float, default=1.5, help="mm around the lines")
    args = parser.parse_args()
    folder, animate = _case(Path(args.work), args.case, args.frames)
    stored = np.load(folder / "truth.npz")
    truth = {k: stored[k] for k in ("vertices", "without_detail", "detail_height", "detail_mask", "head_pose",
                                     "mocap_from_scan", "video_mocap_frames")}
    rest = read_result(animate).mesh.vertices
    deepest = np.abs(truth["detail_height"]).max(axis=0)
    distance, _ = cKDTree(rest[deepest > 0.03]).query(rest, distance_upper_bound=args.grow)
    region = np.isfinite(distance)
    report = {"case": args.case, "region_vertices": int(region.sum()), "grow_mm": args.grow,
              "flow": _flow_error(folder, animate, truth, region), "variants": []}
    print(json.dumps(report["flow"]), flush=True)
    for geometry, placement in VARIANTS:
        row = _run(folder, animate, truth, region, geometry, placement)
        report["variants"].append(row)
        print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in row.items()}), flush=True)
    (Path(args.work) / f"placement_{args.case}.json").write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
