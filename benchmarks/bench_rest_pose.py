"""A studio's take as it arrives (issue 28): a resting face that is not the scan's, a head that sways, the defaults.

Every case (``benchmarks/cases.py``) is written to disk as a user holds it (scan OBJ, C3D take, JSON map,
truth) and run through ``facecap animate`` **as the README shows it**: the command line with its defaults
(``facecap.cli.main``, in this process). Beside it, in the same run:

- ``oracle``: the same thin shell driven by the exact skin displacements from the *scan* under the markers
  (``truth[t, marker_vertices] - scan[marker_vertices]``): with a resting expression the truth of frame 0 is
  not the scan, and the oracle keeps it, as a user wants.
- ``before``: the defaults of the release before issue 28: ``--stabilize off``, ``--rest-pose scan`` (the warp
  maps the rest frame exactly onto the scan) and the rest average without its per-frame rigid fit.
- ``stabilize auto``: ``--stabilize auto --rest-pose scan``: the old best option.
- ``new``: the command's defaults now (``--stabilize auto``, ``--rest-pose auto``).

Errors are :func:`facecap.report.evaluate_result.evaluate_result`'s (a stabilised result in the world, with
its head motion, against the truth with the true head motion), mean over every vertex and frame, mm; split
into the part across the skin (along the truth's normal) and the part along it, and per region. The rest
pose the run chose and why (``report.json``) is printed beside.

Protocol: the tuned cases choose every constant of ``facecap.markers.resting_expression``; the held-out
cases (``--held-out``) are run once, after, and reported as they come.

Run (about 40 s a case on 2 cores)::

    python benchmarks/bench_rest_pose.py                    # tuned cases
    python benchmarks/bench_rest_pose.py --held-out         # once, for the report
    python benchmarks/bench_rest_pose.py --cases studio_a_real tuned_rest_real --save out.json
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import json
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any, Iterator

import igl
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from cases import Case, add_case_options, chosen_cases, make_case  # noqa: E402

from facecap.cli import main as facecap_main  # noqa: E402
from facecap.deform.thin_shell import ThinShellSolver  # noqa: E402
from facecap.errors import FacecapWarning  # noqa: E402
from facecap.report.evaluate_performance import evaluate_performance  # noqa: E402
from facecap.report.evaluate_result import result_and_truth_mm  # noqa: E402
from facecap.synth import SyntheticCase, write_synthetic_case  # noqa: E402
from facecap.io.ict_sample import load_ict_sample

N_FRAMES = 600

RUNS = {
    "before": ["--stabilize", "off", "--rest-pose", "scan"],
    "stabilize auto": ["--stabilize", "auto", "--rest-pose", "scan"],
    "new": [],
}
"""Command-line options of each run beyond the files (``new``: the defaults)."""


@contextlib.contextmanager
def rest_average_before_issue_28() -> Iterator[None]:
    """The rest average of the release before issue 28: the window's frames averaged as captured."""
    module = importlib.import_module("facecap.pipelines.animate_scan")
    current = module.rest_average

    def before(P: np.ndarray, rest_frame: int, sigma_frames: float, **_: Any) -> np.ndarray:
        rest = P[rest_frame]
        if sigma_frames <= 0:
            return rest
        reach = int(2.5 * sigma_frames + 0.5)
        lo, hi = max(0, rest_frame - reach), min(P.shape[0], rest_frame + reach + 1)
        w = np.exp(-0.5 * ((np.arange(lo, hi) - rest_frame) / sigma_frames) ** 2)
        dev = P[lo:hi] - rest[None]
        seen = np.isfinite(dev).all(axis=2)
        weight = w[:, None] * seen
        mean = np.einsum("tk,tkc->kc", weight, np.where(seen[..., None], dev, 0.0)) / weight.sum(axis=0)[:, None]
        return rest + mean

    module.rest_average = before
    try:
        yield
    finally:
        module.rest_average = current


def split_error(result_mm: np.ndarray, truth_mm: np.ndarray, F: np.ndarray) -> dict[str, float]:
    """Mean error (mm) across the skin (along the truth's vertex normals) and along it, every vertex and frame."""
    across, along = [], []
    for t in range(truth_mm.shape[0]):
        N = igl.per_vertex_normals(truth_mm[t].astype(np.float64), F)
        e = result_mm[t].astype(np.float64) - truth_mm[t]
        normal = np.einsum("nd,nd->n", e, N)
        across.append(np.abs(normal).mean())
        along.append(np.linalg.norm(e - normal[:, None] * N, axis=1).mean())
    return {"across_mm": float(np.mean(across)), "along_mm": float(np.mean(along))}


def oracle_error(synthetic: SyntheticCase, region_labels: np.ndarray, region_names: list[str]) -> dict[str, Any]:
    """The shell driven by the exact skin displacements from the scan (the best these markers allow)."""
    V, F, mv = synthetic.scan.vertices, synthetic.scan.faces, synthetic.marker_vertices
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FacecapWarning)
        solver = ThinShellSolver(V, F, mv)
    truth = synthetic.truth_vertices
    result = V.astype(np.float32)[None] + solver.displacements(truth[:, mv] - V[mv].astype(np.float32))
    error = evaluate_performance(result, truth, region_labels=region_labels, region_names=region_names)
    return {"mean_mm": error.mean_mm, **split_error(result, truth, F),
            "regions": {k: v["mean_mm"] for k, v in error.to_dict()["regions"].items()}}


def run_case(case: Case, n_frames: int) -> dict[str, Any]:
    """Every run of one case: errors, their split, and what the command chose."""
    sample = load_ict_sample()
    names = list(sample.region_names)
    synthetic = make_case(case, n_frames=n_frames)
    row: dict[str, Any] = {"oracle": oracle_error(synthetic, sample.region_labels, names)}
    with tempfile.TemporaryDirectory() as tmp:
        files = write_synthetic_case(synthetic, Path(tmp) / "case", region_labels=sample.region_labels,
                                     region_names=names)
        for name, options in RUNS.items():
            out = Path(tmp) / name.replace(" ", "_")
            argv = ["animate", "--scan", str(files.scan), "--markers", str(files.markers), "--map", str(files.map),
                    "--out", str(out), "-q", *options]
            with warnings.catch_warnings(), (rest_average_before_issue_28() if name == "before"
                                             else contextlib.nullcontext()):
                warnings.simplefilter("ignore", FacecapWarning)
                status = facecap_main(argv)
            if status != 0:
                raise RuntimeError(f"{case.name}: facecap {' '.join(argv)} exited with {status}")
            result_mm, truth_mm, truth = result_and_truth_mm(files.truth, out)
            error = evaluate_performance(result_mm, truth_mm, region_labels=truth["region_labels"],
                                         region_names=[str(s) for s in truth["region_names"]])
            report = json.loads((out / "report.json").read_text())
            row[name] = {"mean_mm": error.mean_mm, **split_error(result_mm, truth_mm, synthetic.scan.faces),
                         "regions": {k: v["mean_mm"] for k, v in error.to_dict()["regions"].items()},
                         "rest_pose": report["rest_pose"]["mode"], "coherence": report["rest_pose"]["coherence"],
                         "motion_z": report["rest_pose"]["motion_z"], "above_noise": report["rest_pose"]["above_noise"],
                         "offset_error_mm": report["rest_pose"]["offset_error_mm"],
                         "placement_sd_mm": report["rest_pose"]["placement_sd_mm"],
                         "stabilized": report["head_motion"]["stabilized"],
                         "pose_from": report["head_motion"]["pose_from"]}
    return row


def table(rows: dict[str, dict[str, Any]]) -> str:
    """Markdown: one line per case and run."""
    out = ["| case | oracle | before | stabilize auto | **new** | new: across / along the skin | new / before "
           "| rest pose chosen (x noise, coherence, motion z) | head pose |",
           "|---|---|---|---|---|---|---|---|---|"]
    for name, row in rows.items():
        new = row["new"]
        out.append(f"| {name} | {row['oracle']['mean_mm']:.3f} | {row['before']['mean_mm']:.3f} "
                   f"| {row['stabilize auto']['mean_mm']:.3f} | **{new['mean_mm']:.3f}** "
                   f"| {new['across_mm']:.3f} / {new['along_mm']:.3f} "
                   f"| {new['mean_mm'] / row['before']['mean_mm']:.2f} "
                   f"| {new['rest_pose']} ({new['above_noise']:.1f}, {new['coherence']:.2f}, {new['motion_z']:.0f}) "
                   f"| {new['pose_from'] or 'none (still)'} |")
    ratios = [row["new"]["mean_mm"] / row["stabilize auto"]["mean_mm"] for row in rows.values()]
    out.append(f"\nnew / stabilize auto: median {statistics.median(ratios):.2f}, worst {max(ratios):.2f}")
    regions = next(iter(rows.values()))["new"]["regions"]
    out.append("\n| case | run | " + " | ".join(regions) + " |")
    out.append("|---|---|" + "---|" * len(regions))
    for name, row in rows.items():
        for run in ("oracle", "before", "new"):
            out.append(f"| {name} | {run} | " + " | ".join(f"{row[run]['regions'][k]:.3f}" for k in regions) + " |")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_case_options(p)
    p.add_argument("--frames", type=int, default=N_FRAMES)
    p.add_argument("--save", default=None, help="raw figures as JSON")
    args = p.parse_args(argv)
    rows: dict[str, dict[str, Any]] = {}
    for case in chosen_cases(args):
        t = time.perf_counter()
        rows[case.name] = run_case(case, args.frames)
        r = rows[case.name]
        print(f"{case.name}: oracle {r['oracle']['mean_mm']:.3f}, "
              + ", ".join(f"{k} {r[k]['mean_mm']:.3f}" for k in RUNS)
              + f" ({r['new']['rest_pose']}: x noise {r['new']['above_noise']:.1f}, coherence {r['new']['coherence']:.2f}, "
                f"motion z {r['new']['motion_z']:.1f}, offset error {r['new']['offset_error_mm']:.2f} mm; "
                f"{time.perf_counter() - t:.0f} s)",
              file=sys.stderr, flush=True)
    if args.save:
        Path(args.save).write_text(json.dumps(rows, indent=1))
    print(f"python {' '.join(sys.argv)}\n")
    print(table(rows))


if __name__ == "__main__":
    main()
