"""Accuracy of the scan workflow against `facecap animate` on generated takes (issue bar: blend <= 0.5 x animate).

Each take runs the command line as a user would: the generator writes a take, its
scan and the dense truth; ``facecap animate`` (head-band stabilisation) is the
baseline; ``facecap plan-scans`` chooses the frames; each chosen frame's true
expression is scanned by :func:`facecap.synth.write_planned_scans` (20k
vertices, its own topology and scanner frame, noise and holes);
``facecap register-scans --template`` (the neutral scan) and ``facecap blend``
rebuild the take; ``facecap evaluate``'s comparison gives both dense errors.

Usage::

    python benchmarks/bench_scan_accuracy.py                  # the four takes of docs/scan_workflow.md
    python benchmarks/bench_scan_accuracy.py --takes 0:0.001  # seed:tolerance pairs

The defaults are the takes quoted in docs/scan_workflow.md and benchmarks/RESULTS.md,
each tolerance chosen so that the plan has 15-30 scans, as the issue asks.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from facecap.cli import main
from facecap.report.evaluate_result import evaluate_result
from facecap.synth import generate_performance, load_ict_sample, write_planned_scans, write_synthetic_case

DEFAULT_TAKES = ("0:0.001", "1:0.0009", "2:0.0009", "3:0.0011")


def run_take(seed: int, tolerance: float, root: Path, *, frames: int, markers: int, scan_vertices: int) -> dict:
    sample = load_ict_sample()
    case = generate_performance(n_frames=frames, seed=seed, n_markers=markers)
    files = write_synthetic_case(case, root / "inputs", region_labels=sample.region_labels,
                                 region_names=list(sample.region_names))
    cli = ["-q"]
    assert main([*cli, "animate", "--scan", str(files.scan), "--markers", str(files.markers), "--map", str(files.map),
                 "--out", str(root / "animate"), "--stabilize", "auto"]) == 0
    assert main([*cli, "plan-scans", "--markers", str(files.markers), "--out", str(root / "plan.json"),
                 "--tolerance", str(tolerance)]) == 0
    planned = json.loads((root / "plan.json").read_text())["frames"]
    scans = [str(p) for p in write_planned_scans(case, planned, root, target_vertices=scan_vertices)]
    t = time.perf_counter()
    assert main([*cli, "register-scans", "--plan", str(root / "plan.json"), "--markers", str(files.markers),
                 "--scans", *scans, "--template", str(files.scan), "--out", str(root / "bases")]) == 0
    register_s = time.perf_counter() - t
    assert main([*cli, "blend", "--bases", str(root / "bases"), "--markers", str(files.markers),
                 "--out", str(root / "blend")]) == 0
    animate = evaluate_result(files.truth, root / "animate")
    blend = evaluate_result(files.truth, root / "blend")
    return {
        "seed": seed, "tolerance": tolerance, "scans": len(planned), "animate_mm": animate.mean_mm,
        "blend_mm": blend.mean_mm, "ratio": blend.mean_mm / animate.mean_mm, "register_s": register_s,
        "blend_regions_mm": {name: r.mean_mm for name, r in blend.regions.items()},
    }


def main_bench() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--takes", nargs="+", default=list(DEFAULT_TAKES), help="seed:tolerance pairs")
    parser.add_argument("--frames", type=int, default=600)
    parser.add_argument("--markers", type=int, default=90)
    parser.add_argument("--scan-vertices", type=int, default=20_000)
    args = parser.parse_args()
    rows = []
    for take in args.takes:
        seed, tolerance = take.split(":")
        with tempfile.TemporaryDirectory(prefix="facecap_scan_accuracy_") as tmp:
            row = run_take(int(seed), float(tolerance), Path(tmp), frames=args.frames, markers=args.markers,
                           scan_vertices=args.scan_vertices)
        rows.append(row)
        print("RESULT", json.dumps(row), flush=True)
    print("| seed | tolerance | scans | animate | blend | ratio (bar 0.5) |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['seed']} | {100 * r['tolerance']:.2f} % | {r['scans']} | {r['animate_mm']:.3f} mm "
              f"| {r['blend_mm']:.3f} mm | {r['ratio']:.2f} |")


if __name__ == "__main__":
    main_bench()
