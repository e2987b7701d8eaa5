"""Speed and memory of the scan workflow (Huang et al. 2011): registering the scans and blending the take.

One run prints a ``RESULT {json}`` line and a markdown table::

    python benchmarks/bench_scan_workflow.py [--frames 1500] [--scans 20] [--scan-vertices 80000] [--textured]

What is measured (wall time; generating the take and the scans is not timed):

registration
    :func:`facecap.pipelines.register_planned_scans` on
    ``--scans`` simulated scans of about ``--scan-vertices`` vertices each
    (:func:`facecap.synth.scan_expression.scan_expression` of the ground truth
    at the planned frames: new sampling, 0.05 mm noise, holes, own scanner
    frame), with the first scan as the template, so every basis has that
    scan's ~80k vertices: marker-to-scan ICP with the subspace refinement,
    the large-scale template registration (eq. 7) of each scan, and the bases
    fitted to their markers. The plan is forced to ``--scans`` frames
    (``tolerance=0, max_frames=scans``). Bar: 20 scans of 80k vertices in
    under 10 minutes on 2 cores (the paper: 5 hours). With ``--textured`` every
    scan carries a 0.25 mm colour texture of the skin with pores
    (:func:`facecap.synth.bake_skin_albedo`, baked once, not timed), so the
    default aligns each by colour too; bar (issue 31): under 60 s. The
    registration runs with its defaults (worker processes on every core for
    scans this large) and, as the baseline in the same run, again in one
    process (``workers=1``).
blend
    :func:`facecap.pipelines.blend_take` for the whole take:
    NNLS weights per frame (eq. 12) and the dense performance written to
    ``vertices.npy`` (1500 x 80k x 3 float32 = 1.4 GB). Bar: under 10 s.
    Baseline in the same run: the weights by a loop of
    ``scipy.optimize.nnls`` over the frames, and the dense product by
    ``numpy.einsum``, neither writing anything.

``other_cores`` is the CPU other processes used meanwhile (the machine is shared);
``peak_rss_gb`` is the process's ``ru_maxrss`` at the end.
"""

from __future__ import annotations

import argparse
import json
import platform
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.optimize import nnls

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _load import Window, peak_rss_gb  # noqa: E402

from facecap.pipelines import blend_take, plan_scans, register_planned_scans, replay_conditioning  # noqa: E402
from facecap.io.registered_scans import read_registered_scans  # noqa: E402
from facecap.synth import bake_skin_albedo, generate_performance, write_planned_scans, write_synthetic_case  # noqa: E402
from facecap.io.ict_sample import load_ict_sample


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=1500)
    ap.add_argument("--scans", type=int, default=20)
    ap.add_argument("--scan-vertices", type=int, default=80_000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--textured", action="store_true", help="scans with 0.25 mm colour textures (aligned by colour)")
    ap.add_argument("--out-dir", default=None, help="where the inputs and outputs go (default: the temp folder)")
    args = ap.parse_args(argv)

    root = Path(tempfile.mkdtemp(prefix="facecap-bench-scans-", dir=args.out_dir))
    try:
        sample = load_ict_sample()
        case = generate_performance(n_frames=args.frames, n_markers=90, seed=args.seed, sample=sample)
        files = write_synthetic_case(case, root / "inputs", region_labels=sample.region_labels,
                                     region_names=list(sample.region_names))
        with Window() as w_plan:
            plan = plan_scans(files.markers, root / "plan.json", tolerance=0.0, max_frames=args.scans,
                              progress=False)
        colour = {}
        if args.textured:
            colour = dict(skin_texture=bake_skin_albedo(case.scan, seed=args.seed), file_format="obj")
        scan_paths = write_planned_scans(case, plan.frames, root, target_vertices=args.scan_vertices,
                                         **{"file_format": "ply", **colour})

        serial = None
        if args.textured:  # the baseline: the same registration in this one process
            with Window() as w_serial:
                serial = register_planned_scans(root / "plan.json", files.markers, scan_paths, root / "bases_serial",
                                                progress=False, workers=1)
        with Window() as w_reg:
            report = register_planned_scans(root / "plan.json", files.markers, scan_paths, root / "bases",
                                            progress=False)
        rss_after_registration = peak_rss_gb()
        scan_sizes = [entry["vertices"] for entry in report["scans"]]

        with Window() as w_blend:
            blend = blend_take(root / "bases", files.markers, root / "blend", progress=False)
        written = (root / "blend" / "vertices.npy").stat().st_size

        # baseline: the same weights by scipy's NNLS per frame, and the product by einsum
        folder = read_registered_scans(root / "bases")
        weights = np.load(root / "blend" / "weights.npy")
        from facecap.io.read_markers import read_markers

        take = read_markers(files.markers).select(folder["marker_labels"])
        X = replay_conditioning(take, folder["plan"]["conditioning"]).positions.reshape(args.frames, -1)
        A = folder["basis_markers"].reshape(len(plan.frames), -1).T
        with Window() as w_scipy:
            w_ref = np.stack([nnls(A, x)[0] for x in X])
        bases = folder["bases"].astype(np.float32)
        with Window() as w_einsum:
            for start in range(0, args.frames, 100):
                np.einsum("tk,knc->tnc", weights[start:start + 100].astype(np.float32), bases)
        result = {
            "machine": {"cpu": platform.processor() or platform.machine(), "python": platform.python_version()},
            "frames": args.frames, "scans": len(plan.frames), "scan_vertices": scan_sizes,
            "template_vertices": int(folder["template"].n_vertices),
            "plan_s": w_plan.seconds,
            "textured": args.textured, "colour_alignment": report["colour_alignment"],
            "registration_s": w_reg.seconds, "registration_other_cores": w_reg.other_cores,
            "registration_workers": report["workers"],
            "registration_stage_s": report["timings"],
            "baseline_one_process_s": None if serial is None else w_serial.seconds,
            "baseline_one_process_stage_s": None if serial is None else serial["timings"],
            "max_basis_difference_one_process_mm": None if serial is None else float(np.abs(
                read_registered_scans(root / "bases")["bases"] - read_registered_scans(root / "bases_serial")["bases"]).max()),
            "registration_mm": report["registration_mm"],
            "blend_s": w_blend.seconds, "blend_other_cores": w_blend.other_cores,
            "blend_weights_s": blend["weights_s"], "blend_written_gb": written / 1e9,
            "baseline_scipy_nnls_s": w_scipy.seconds,
            "weights_max_diff": float(np.abs(w_ref - weights).max()),
            "baseline_einsum_s": w_einsum.seconds,
            "peak_rss_gb_after_registration": rss_after_registration,
            "peak_rss_gb": peak_rss_gb(),
        }
    finally:
        shutil.rmtree(root, ignore_errors=True)
    print("RESULT " + json.dumps(result))
    r = result
    print(f"| registration, {r['scans']} scans of {min(r['scan_vertices']):,}-{max(r['scan_vertices']):,} vertices "
          f"(template {r['template_vertices']:,}) | {r['registration_s']:.1f} s | other cores "
          f"{r['registration_other_cores']:.2f} | residual to scans {max(r['registration_mm']):.3f} mm max; "
          f"{r['registration_workers']} worker(s); colour alignment {r['colour_alignment']} |")
    if r["baseline_one_process_s"] is not None:
        print(f"| baseline: the same registration in one process | {r['baseline_one_process_s']:.1f} s | | "
              f"bases differ by {r['max_basis_difference_one_process_mm']:.2g} mm at most |")
    print(f"| blend, {r['frames']} frames (weights {r['blend_weights_s']:.2f} s; {r['blend_written_gb']:.2f} GB written) "
          f"| {r['blend_s']:.1f} s | other cores {r['blend_other_cores']:.2f} | baseline: scipy nnls loop "
          f"{r['baseline_scipy_nnls_s']:.2f} s + einsum {r['baseline_einsum_s']:.2f} s |")
    print(f"| peak memory | {r['peak_rss_gb']:.2f} GB | | |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
