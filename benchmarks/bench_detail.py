"""The detail layer's bars on generated takes (issue 30): tuned and held-out cases, beside the baselines.

Each case: ``write_detail_case`` (studio lights, fine lines, 25 fps, markers drawn, 8-bit sRGB footage from
two 1384x1038 cameras; the brow raise, frown, smile and squint in turn), ``facecap animate`` with its
defaults, then ``facecap detail`` with its defaults, as the README shows them. Beside it, in the same run:
adding nothing (the ratio 1 by definition), the paper's single-frame Lambertian baseline (``--uniform-albedo``,
no specular, no temporal term, nothing left out: ``capture_detail(specular=False, rest_misfit_limit=inf,
options={'temporal': 0})``) and a "dark is deep" high-pass (the image's deviation from its slow gain, read as
depth with the scale that fits the truth best: generous to it). The metrics are :mod:`detail_metrics`' (both
placements, nothing invented, stable).

Cases (seed, identity, markers, appearance): ``tuned0`` and ``tuned1`` are what the defaults were chosen on;
``held2``, ``held3`` (other identities and seeds) and ``indep4`` (the independent appearance: microfacet
specular with Fresnel, a blurred diffuse, other lights, double creases) are held out, run once.

    python benchmarks/bench_detail.py [--cases tuned0,held2] [--frames 41] [--work DIR] [--no-baselines]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parent))
from detail_metrics import detail_metrics  # noqa: E402

CASES = {"tuned0": (0, None, None, "phong"), "tuned1": (1, 2, 60, "phong"),
         "held2": (102, 4, 90, "phong"), "held3": (103, 6, 60, "phong"), "indep4": (104, 5, None, "independent")}
TUNED = {"tuned0", "tuned1"}


def _case(work: Path, name: str, frames: int) -> tuple[Path, Path]:
    from facecap.synth.generate_performance import random_identity
    from facecap.synth.write_detail_case import write_detail_case

    seed, identity, markers, appearance = CASES[name]
    folder, animate = work / name, work / f"{name}_animate"
    if not (folder / "truth.npz").exists():
        write_detail_case(folder, n_frames=frames, seed=seed, n_markers=markers, appearance=appearance,
                          identity=None if identity is None else random_identity(identity))
    if not (animate / "performance.json").exists():
        subprocess.run(["facecap", "-q", "animate", "--scan", str(folder / "scan.obj"), "--markers",
                        str(folder / "take.c3d"), "--map", str(folder / "map.json"), "--out", str(animate)], check=True)
    return folder, animate


def _detail(folder: Path, animate: Path, out: Path, extra: list[str]) -> float:
    if not (out / "performance.json").exists():
        t = time.perf_counter()
        subprocess.run(["facecap", "-q", "detail", "--result", str(animate), "--cameras", str(folder / "cameras.json"),
                        "--video", str(folder / "cam_left"), str(folder / "cam_right"),
                        "--lights", str(folder / "lights.json"), "--out", str(out), "--map-size", "0", *extra],
                       check=True)
        return time.perf_counter() - t
    return float("nan")


def _lambertian(folder: Path, animate: Path, out: Path) -> float:
    if (out / "performance.json").exists():
        return float("nan")
    from facecap.cameras import read_camera_file, read_light_file
    from facecap.pipelines import capture_detail

    setup = read_camera_file(folder / "cameras.json")
    t = time.perf_counter()
    capture_detail(animate, setup.cameras, [folder / "cam_left", folder / "cam_right"],
                   read_light_file(folder / "lights.json"), out, video_rate_hz=setup.video_rate_hz,
                   per_sample_albedo=False, specular=False, rest_misfit_limit=float("inf"), options={"temporal": 0.0},
                   map_size=0)
    return time.perf_counter() - t


def _dark_is_deep(folder: Path, animate: Path, detail: Path) -> dict:
    """The "dark is deep" high-pass on the detail run's region: each sample's deviation from the base's Lambertian
    shading under its slow gain (no albedo: freckles, moles, brows and the flush read as depth), times the one
    scale that fits the true heights best over the whole take (generous to it)."""
    import numpy as np

    from facecap.cameras import read_camera_file, read_light_file
    from facecap.mesh.vertex_normals import vertex_normals
    from facecap.sfs import DetailFrameStage, shade_frame

    setup = read_camera_file(folder / "cameras.json")
    truth = np.load(folder / "truth.npz")
    video = truth["video_mocap_frames"]
    region = np.load(detail / "detail_region.npy")
    lights = read_light_file(folder / "lights.json")
    bits = json.loads((folder / "footage.json").read_text())["bits"]
    footage = [str(folder / "cam_left"), str(folder / "cam_right")]
    stage = DetailFrameStage(str(animate.resolve()), setup.cameras, footage, lights, video.astype(float), region,
                             np.ones(region.size), 0.0, 1.0, "srgb" if bits == 8 else "linear", {"blur_px": 0.0})
    deviation = np.zeros((video.size, region.size))
    for j in range(video.size):
        frame, _ = stage.observe(j)
        predicted, _, _ = shade_frame(frame, np.zeros(region.size), 1.0, 0.0, 1.0, lights.ambient)
        ok = (frame.weight > 0) & (predicted > 1e-9)
        w = np.where(ok, frame.weight, 0.0)
        ratio = np.where(ok, frame.intensity / np.where(ok, predicted, 1.0) - 1.0, 0.0)
        deviation[j] = (w * ratio).sum(axis=0) / np.maximum(w.sum(axis=0), 1e-12)
    true = np.stack([truth["detail_height"][t][region] for t in video])
    scale = float(np.sum(deviation * true) / max(np.sum(deviation ** 2), 1e-300))
    from facecap.io.read_result import read_result

    F = read_result(animate).mesh.faces
    frame_of = {int(t): j for j, t in enumerate(video)}

    def added(t: int, A: np.ndarray) -> np.ndarray:
        D = A.copy()
        D[region] += scale * deviation[frame_of[t]][:, None] * vertex_normals(A, F, region)
        return D

    out = detail_metrics(folder, animate, added)
    out["scale_mm"] = scale
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--cases", default=",".join(CASES))
    parser.add_argument("--frames", type=int, default=41, help="mocap frames at 50 Hz (21 video frames at 25 fps)")
    parser.add_argument("--work", default="benchmarks/_work/detail")
    parser.add_argument("--no-baselines", action="store_true")
    args = parser.parse_args()
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    rows = {}
    for name in args.cases.split(","):
        folder, animate = _case(work, name, args.frames)
        row = {"set": "tuned" if name in TUNED else "held-out"}
        seconds = _detail(folder, animate, work / f"{name}_detail", [])
        row["detail"] = detail_metrics(folder, animate, work / f"{name}_detail")
        row["detail"]["seconds"] = seconds
        if not args.no_baselines:
            seconds = _lambertian(folder, animate, work / f"{name}_lambertian")
            row["lambertian"] = detail_metrics(folder, animate, work / f"{name}_lambertian")
            row["lambertian"]["seconds"] = seconds
            row["dark_is_deep"] = _dark_is_deep(folder, animate, work / f"{name}_detail")
        rows[name] = row
        print(name, json.dumps({k: ({m: (round(x, 4) if isinstance(x, float) else x) for m, x in v.items()
                                     if m != "frames"} if isinstance(v, dict) else v) for k, v in row.items()}))
    (work / "results.json").write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
