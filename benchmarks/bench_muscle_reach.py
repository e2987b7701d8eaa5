"""The muscle model's reach: how close it can get to a generated take's truth when it is told everything (issue 11).

``bench_muscle_accuracy.py`` measures the muscle solve as a user runs it, from the take's
markers. This benchmark asks what the anatomy itself can represent, so that a bar it misses can
be told apart from a bar no solve of this model can meet:

- the "markers" are ``--points`` scan vertices spread over the model's face by farthest-point
  sampling (300 by default, against a take's 40-120 markers), on the skin itself (no marker
  height), placed exactly at the truth's positions (no noise, no gaps, no head motion);
- every ``--stride``-th frame of the take (at most ``--frames``) is solved in order, each
  warm-started from the last (:class:`facecap.muscles.MuscleSolver`, up to ``--warm-steps``
  Gauss-Newton steps a frame);
- the error is the skin against the truth, mean over the face vertices the model carries
  (meshed, not far outside it), per frame, then per region of the ICT sample's labels.

Beside it, in the same run: ``facecap animate --stabilize auto`` on the real (noisy, sparse)
take, its stabilised face against the expression-only truth at the same frames and vertices.
A model whose reach is above ``animate``'s error cannot meet a bar of 1.1 times ``animate``'s
error by any solve.

Usage::

    python benchmarks/bench_muscle_reach.py                            # default_0 and studio_a_real
    python benchmarks/bench_muscle_reach.py --cases tuned_speech --points 600
    python benchmarks/bench_muscle_reach.py --solver-options '{"muscle_strength": ...}'
    python benchmarks/bench_muscle_reach.py --jaw rotational            # the jaw opening along its arc

The anatomy is ``build_anatomy(scan, n_tets=--tets)``, kept under ``--work`` for later runs (fTetWild
meshes differ from run to run, so compare options on one kept model).
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

from _meshes import farthest_point_markers  # noqa: E402
from cases import case_by_name, make_case  # noqa: E402

from facecap.anatomy import build_anatomy, load_anatomy  # noqa: E402
from facecap.cli import main  # noqa: E402
from facecap.errors import FacecapWarning  # noqa: E402
from facecap.muscles import FOLLOWER_WEIGHT_LIMIT, MuscleSolver  # noqa: E402
from facecap.report.evaluate_result import result_and_truth_mm  # noqa: E402
from facecap.synth import write_synthetic_case  # noqa: E402
from facecap.io.ict_sample import load_ict_sample


def run_case(name: str, work: Path, *, n_tets: int, points: int, stride: int, n_frames: int, warm_steps: int,
             options: dict, jaw: str = "linear") -> dict:
    sample = load_ict_sample()
    synthetic = make_case(case_by_name(name), n_frames=600, jaw=jaw)
    model = work / f"model_{name}_{n_tets}"
    if not (model / "anatomy.json").is_file():
        build_anatomy(synthetic.scan, n_tets=n_tets).save(model)
    anatomy = load_anatomy(model)
    face = np.flatnonzero(np.asarray(anatomy.skin_meshed)
                          & (np.abs(np.asarray(anatomy.skin_weights)).max(axis=1) <= FOLLOWER_WEIGHT_LIMIT))
    V = synthetic.scan.vertices
    chosen = face[farthest_point_markers(V[face], points, start=0)]
    frames = np.arange(0, synthetic.truth_vertices.shape[0], stride)[:n_frames]

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FacecapWarning)
        solver = MuscleSolver(anatomy, chosen, V[chosen], max_warm_steps=warm_steps, **options)
        t = time.perf_counter()
        previous, skins = None, []
        for f in frames:
            previous = solver.solve_frame(synthetic.truth_vertices[f][chosen].astype(np.float64), previous)
            skins.append(previous.skin[face])
        solve_s = time.perf_counter() - t
    truth = synthetic.truth_vertices[frames][:, face].astype(np.float64)
    muscles = np.linalg.norm(np.asarray(skins) - truth, axis=2)

    with tempfile.TemporaryDirectory(prefix="facecap_muscle_reach_") as tmp:
        files = write_synthetic_case(synthetic, Path(tmp) / "in", region_labels=sample.region_labels,
                                     region_names=list(sample.region_names))
        out = Path(tmp) / "animate"
        assert main(["-q", "animate", "--scan", str(files.scan), "--markers", str(files.markers), "--map",
                     str(files.map), "--out", str(out), "--stabilize", "auto"]) == 0
        result, truth_mm, _ = result_and_truth_mm(files.truth, out, frame="stabilized")
    animate = np.linalg.norm(result[frames][:, face].astype(np.float64) - truth_mm[frames][:, face], axis=2)

    labels = np.asarray(sample.region_labels)[face]
    regions = {}
    for r, region in enumerate(sample.region_names):
        on = labels == r
        if on.any():
            regions[region] = (float(muscles[:, on].mean()), float(animate[:, on].mean()))
    per_frame = muscles.mean(axis=1)
    return {"case": name, "jaw": jaw, "points": points, "frames": len(frames), "face_vertices": int(face.size),
            "markers": int(synthetic.n_face_markers), "muscles_mm": float(muscles.mean()),
            "muscles_worst_frame_mm": float(per_frame.max()), "animate_mm": float(animate.mean()),
            "ratio": float(muscles.mean() / animate.mean()), "regions_mm": regions, "solve_s": solve_s}


def main_bench() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", nargs="+", default=["default_0", "studio_a_real"],
                   help="generated takes of benchmarks/cases.py [default_0 studio_a_real]")
    p.add_argument("--points", type=int, default=300, help="skin points the model is fitted to [300]")
    p.add_argument("--stride", type=int, default=8)
    p.add_argument("--frames", type=int, default=75)
    p.add_argument("--warm-steps", type=int, default=3)
    p.add_argument("--tets", type=int, default=20000)
    p.add_argument("--work", default=None, help="keep the models here [a temporary folder]")
    p.add_argument("--solver-options", default="{}", help="JSON MuscleSolver / MuscleModel options")
    p.add_argument("--jaw", choices=("linear", "rotational"), default="linear",
                   help="the generator's jaw opening: ICT's straight lines, or along the jaw's arc [linear]")
    args = p.parse_args()
    work = Path(args.work) if args.work else Path(tempfile.mkdtemp(prefix="bench-muscle-reach-"))
    work.mkdir(parents=True, exist_ok=True)
    rows = []
    for name in args.cases:
        row = run_case(name, work, n_tets=args.tets, points=args.points, stride=args.stride, n_frames=args.frames,
                       warm_steps=args.warm_steps, options=json.loads(args.solver_options), jaw=args.jaw)
        rows.append(row)
        print("RESULT", json.dumps(row), flush=True)
    regions = list(rows[0]["regions_mm"])
    print("| take | jaw | markers | points fitted | frames | muscles fitted to the truth (mm) | worst frame | animate from the "
          "take (mm) | ratio | " + " | ".join(f"{r}, muscles / animate" for r in regions) + " |")
    print("|---" * (9 + len(regions)) + "|")
    for r in rows:
        print(f"| {r['case']} | {r['jaw']} | {r['markers']} | {r['points']} | {r['frames']} | {r['muscles_mm']:.3f} | "
              f"{r['muscles_worst_frame_mm']:.3f} | {r['animate_mm']:.3f} | **{r['ratio']:.2f}** | "
              + " | ".join(f"{r['regions_mm'][g][0]:.2f} / {r['regions_mm'][g][1]:.2f}" for g in regions) + " |")


if __name__ == "__main__":
    main_bench()
