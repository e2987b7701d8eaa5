"""Accuracy of the scan workflow against `facecap animate` (issue bars: blend <= 0.5 x animate on every
held-out take, every basis within 0.3 mm of the truth at its own frame).

Each take of ``cases.py`` runs the command line as a user would: the generator writes a take,
its scan and the dense truth; ``facecap animate`` (``--stabilize auto`` and ``off``) is the
baseline; ``facecap plan-scans`` chooses the frames; each chosen frame's true expression is
scanned by :func:`facecap.synth.write_planned_scans` (20k vertices, its own topology and
scanner frame, noise and holes; with ``--colors`` also colour: the skin's albedo with each scan's own
exposure, shading and sensor noise, a coloured scan of the neutral as ``--template-texture`` and
``--color-alignment``);
``facecap register-scans --template`` (the neutral scan) and
``facecap blend`` rebuild the take; ``facecap.report.evaluate_result`` gives the dense errors.

Errors are in the world by default (each result moved by the head motion it wrote, against the
truth moved by the true head motion: what a user gets), and also in the stabilised frame (the
stabilised face against the expression-only truth).

Stage by stage against the truth, besides the final numbers:

- the take's stabilisation: rotation error of the stabilising transform, degrees;
- each basis at its own frame, mean over all template vertices: in the world (moved by the
  blend's head motion of that frame), in the stabilised frame, and after the best rigid
  alignment to the truth (what the registration got wrong beyond a pose);
- each basis's error split across the skin (along the truth's normals, mean absolute) and along it
  (the tangential part, mean length), beside ``animate``'s at the same frames: a surface matched to
  its scan has little error across, so what is left along the skin is correspondence;
- what register-scans reports per basis without truth (marker residual after the fit, how far
  the fit moved the surface).

Usage::

    python benchmarks/bench_scan_accuracy.py                       # every tuned case
    python benchmarks/bench_scan_accuracy.py --cases studio_a_real default_0
    python benchmarks/bench_scan_accuracy.py --held-out            # the held-out set (report only)
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import igl
import numpy as np
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parent))

from cases import add_case_options, chosen_cases, make_case, scan_case  # noqa: E402

from facecap.cli import main  # noqa: E402
from facecap.io.conditioned_take import read_conditioned_take  # noqa: E402
from facecap.io.registered_scans import read_registered_scans  # noqa: E402
from facecap.markers import rigid_fit  # noqa: E402
from facecap.report.evaluate_result import evaluate_result, result_and_truth_mm  # noqa: E402
from facecap.io import write_mesh  # noqa: E402
from facecap.synth import (SkinRegions, bake_skin_albedo, textured_neutral, write_planned_scans,  # noqa: E402
                           write_synthetic_case)
from facecap.io.ict_sample import load_ict_sample


def _stabilisation_error_deg(synthetic, conditioned) -> np.ndarray:
    """Angle between the take's stabilising rotation and the true one, per frame."""
    M, H = synthetic.mocap_from_scan, synthetic.head_pose
    true = (M[None] @ np.linalg.inv(H) @ np.linalg.inv(M)[None])[:, :3, :3]
    if conditioned.head_rotations is None:
        return np.degrees(Rotation.from_matrix(true).magnitude())
    return np.degrees(Rotation.from_matrix(conditioned.head_rotations @ np.swapaxes(true, 1, 2)).magnitude())


def _basis_errors(synthetic, bases_dir: Path, blend_dir: Path, truth_path: Path, animate_dir: Path) -> dict:
    """Each basis against the truth at its own frame (mean over vertices, mm), and its split across and along the skin."""
    folder = read_registered_scans(bases_dir)
    frames = folder["plan"]["frames"]
    A = folder["output_from_mocap"]
    bases = folder["bases"].astype(np.float64) @ A[:3, :3].T + A[:3, 3]  # template coordinates
    truth = synthetic.truth_vertices[frames].astype(np.float64)
    motion = np.load(blend_dir / "head_motion.npy")[frames] if (blend_dir / "head_motion.npy").is_file() else None
    pose = synthetic.head_pose[frames]
    world_truth = truth @ np.swapaxes(pose[:, :3, :3], 1, 2) + pose[:, None, :3, 3]
    stabilized = np.linalg.norm(bases - truth, axis=2).mean(axis=1)
    fit = rigid_fit(bases, truth)
    rigid_removed = np.linalg.norm(fit.apply(bases) - truth, axis=2).mean(axis=1)
    if motion is not None:
        world_bases = bases @ np.swapaxes(motion[:, :3, :3], 1, 2) + motion[:, None, :3, 3]
        world = np.linalg.norm(world_bases - world_truth, axis=2).mean(axis=1)
    else:
        world = stabilized
    scans = folder["report"]["scans"]
    # across the skin or along it: each basis's error, and animate's at the same frames (the stabilised
    # face against the expression-only truth), split along the truth's vertex normals
    faces = folder["template"].faces
    animate, _, _ = result_and_truth_mm(truth_path, animate_dir, frame="stabilized")
    split = {"basis": [], "animate": []}
    for i, f in enumerate(frames):
        normals = igl.per_vertex_normals(truth[i], faces)
        for name, x in (("basis", bases[i]), ("animate", animate[f].astype(np.float64))):
            e = x - truth[i]
            across = np.einsum("ij,ij->i", e, normals)
            along = np.linalg.norm(e - across[:, None] * normals, axis=1)
            split[name].append((float(np.abs(across).mean()), float(along.mean())))
    return {
        "world_mm": world.tolist(), "stabilized_mm": stabilized.tolist(), "rigid_removed_mm": rigid_removed.tolist(),
        "across_along_mm": split["basis"], "animate_across_along_mm": split["animate"],
        "reported_quality": [s.get("quality", {}) for s in scans],
    }


def split_errors(truth: Path, result: Path) -> dict:
    """Mean error, across and along the skin, on the whole mesh and on the face the scans see (the
    regions other than 'other': ears, scalp and neck are never scanned)."""
    sample = load_ict_sample()
    face = sample.region_labels != list(sample.region_names).index("other")
    out = {}
    for name, mask in (("all", None), ("face", face)):
        e = evaluate_result(truth, result, vertex_mask=mask)
        out[name] = {"mean_mm": e.mean_mm, "across_mm": e.across_mean_mm, "along_mm": e.along_mean_mm}
    return out


def run_case(case, root: Path, *, frames: int, scan_vertices: int, max_scans: int = 30, colors: bool = False,
             textured: bool = False, reperformance: float = 0.0) -> dict:
    sample = load_ict_sample()
    synthetic = make_case(case, n_frames=frames)
    files = write_synthetic_case(synthetic, root / "inputs", region_labels=sample.region_labels,
                                 region_names=list(sample.region_names))
    cli = ["-q"]
    common = ["--scan", str(files.scan), "--markers", str(files.markers), "--map", str(files.map)]
    for mode in ("auto", "off"):
        assert main([*cli, "animate", *common, "--out", str(root / f"animate_{mode}"), "--stabilize", mode]) == 0
    t = time.perf_counter()
    assert main([*cli, "plan-scans", "--markers", str(files.markers), "--out", str(root / "plan.json"),
                 "--tolerance", str(case.tolerance), "--max-scans", str(max_scans)]) == 0
    plan_s = time.perf_counter() - t
    planned = json.loads((root / "plan.json").read_text())["frames"]
    conditioned, _ = read_conditioned_take(root / "plan.conditioned.npz")
    stab_deg = _stabilisation_error_deg(synthetic, conditioned)
    texture: list[str] = []
    colour = {}
    regions = SkinRegions(sample.region_labels, tuple(sample.region_names),  # brows and lips of the skin
                          synthetic.scan.vertices[sample.landmarks[48:60]])
    if colors:  # scanners record colour: the skin's albedo, each scan with its own exposure and shading
        colour = dict(colors=True, albedo_seed=case.scan_seed, skin_regions=regions, file_format="ply")
        # the neutral's own coloured scan (frame 0 is neutral): the template's texture
        neutral = write_planned_scans(synthetic, [0], root / "texture", target_vertices=2 * scan_vertices,
                                      first_seed=case.scan_seed + 1000, **colour)
        texture = ["--template-texture", str(neutral[0]), "--color-alignment"]
    template = files.scan
    if textured:  # scanners deliver a colour texture: every scan its own atlas, the neutral textured in its own
        skin = bake_skin_albedo(synthetic.scan, seed=case.scan_seed, region=regions)
        template = root / "inputs" / "neutral_textured.obj"
        write_mesh(textured_neutral(synthetic.scan, skin, seed=case.scan_seed + 1000), template)
        colour = dict(skin_texture=skin, file_format="obj")
        texture = []  # the default (auto) aligns by colour when every scan and the template are textured
    scans = [str(p) for p in scan_case(case, synthetic, planned, root / "scans", target_vertices=scan_vertices,
                                       reperformance=reperformance, **colour)]
    t = time.perf_counter()
    assert main([*cli, "register-scans", "--plan", str(root / "plan.json"), "--markers", str(files.markers),
                 "--scans", *scans, "--template", str(template), *texture, "--out", str(root / "bases")]) == 0
    register_s = time.perf_counter() - t
    assert main([*cli, "blend", "--bases", str(root / "bases"), "--markers", str(files.markers),
                 "--out", str(root / "blend")]) == 0
    errors = {}
    for name in ("animate_auto", "animate_off", "blend"):
        errors[name] = evaluate_result(files.truth, root / name).mean_mm
        if name != "animate_off":
            errors[name + "_stabilized"] = evaluate_result(files.truth, root / name, frame="stabilized").mean_mm
    blend = evaluate_result(files.truth, root / "blend")
    baseline = min(errors["animate_auto"], errors["animate_off"])
    blend_report = json.loads((root / "blend" / "blend_report.json").read_text())
    return {
        "case": case.name, "held_out": case.held_out, "tolerance": case.tolerance, "scans": len(planned),
        "colors": colors,
        "textured": textured,
        "reperformance": reperformance,
        **{f"{k}_mm": v for k, v in errors.items()},
        "ratio": errors["blend"] / baseline,
        "stabilization_deg": {"median": float(np.median(stab_deg)), "p95": float(np.percentile(stab_deg, 95)),
                              "max": float(stab_deg.max())},
        "blend_pose_correction": blend_report.get("head_pose_correction"),
        "bases": _basis_errors(synthetic, root / "bases", root / "blend", files.truth, root / "animate_auto"),
        "blend_regions_mm": {name: r.mean_mm for name, r in blend.regions.items()},
        "split": {name: split_errors(files.truth, root / name) for name in ("animate_auto", "blend")},
        "plan_s": plan_s, "register_s": register_s,
    }


def main_bench() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_case_options(parser)
    parser.add_argument("--frames", type=int, default=600)
    parser.add_argument("--scan-vertices", type=int, default=20_000)
    parser.add_argument("--max-scans", type=int, default=30,
                        help="cap of plan-scans (the issue's range is 15-30 scans; real-motion takes need more "
                             "than 30 at the default tolerance)")
    parser.add_argument("--colors", action="store_true",
                        help="coloured scans, a coloured neutral scan as --template-texture, --color-alignment")
    parser.add_argument("--textured", action="store_true",
                        help="scans with colour textures (0.25 mm, pores), a textured neutral template, --color-alignment")
    parser.add_argument("--reperformance", type=float, default=0.0,
                        help="each scan is the frame's expression performed again: blendshape weights w -> "
                             "w + R (w n1 + 0.1 n2) (write_planned_scans); 0: the frame itself")
    parser.add_argument("--keep", help="keep each case's folder under this directory")
    args = parser.parse_args()
    cases = chosen_cases(args)
    rows = []
    for case in cases:
        if args.keep:
            root = Path(args.keep) / case.name
            root.mkdir(parents=True, exist_ok=True)
            row = run_case(case, root, frames=args.frames, scan_vertices=args.scan_vertices,
                           max_scans=args.max_scans, colors=args.colors,
                           textured=args.textured, reperformance=args.reperformance)
        else:
            with tempfile.TemporaryDirectory(prefix="facecap_scan_accuracy_") as tmp:
                row = run_case(case, Path(tmp), frames=args.frames, scan_vertices=args.scan_vertices,
                               max_scans=args.max_scans, colors=args.colors,
                           textured=args.textured, reperformance=args.reperformance)
        rows.append(row)
        print("RESULT", json.dumps(row), flush=True)
    print("| case | held out | scans | stabilisation deg (median / max) | animate auto / off | blend | ratio (bar 0.5) "
          "| bases world mean / worst | bases rigid-removed worst | bases across / along | animate across / along |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        b = r["bases"]
        print(f"| {r['case']} | {r['held_out']} | {r['scans']} | {r['stabilization_deg']['median']:.2f} / "
              f"{r['stabilization_deg']['max']:.2f} | {r['animate_auto_mm']:.3f} / {r['animate_off_mm']:.3f} mm "
              f"| {r['blend_mm']:.3f} mm | {r['ratio']:.2f} | {np.mean(b['world_mm']):.3f} / {max(b['world_mm']):.3f} mm "
              f"| {max(b['rigid_removed_mm']):.3f} mm "
              f"| {np.mean([x[0] for x in b['across_along_mm']]):.3f} / {np.mean([x[1] for x in b['across_along_mm']]):.3f} "
              f"| {np.mean([x[0] for x in b['animate_across_along_mm']]):.3f} / "
              f"{np.mean([x[1] for x in b['animate_across_along_mm']]):.3f} |")


if __name__ == "__main__":
    main_bench()
