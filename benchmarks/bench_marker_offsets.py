"""How far ``animate`` is from an oracle shell, and what closes the gap (issue 9, item 3: marker offsets).

The *oracle* is the same :class:`~facecap.deform.thin_shell.ThinShellSolver` driven by the exact
skin displacements under the markers (``truth[t, marker_vertices] - scan[marker_vertices]``), no
conditioning: the best the shell can do with these markers. ``animate`` is
:func:`~facecap.pipelines.animate_scan.animate_scan` with ``stabilize=True`` (the head band when the
take has one, consensus otherwise), defaults otherwise, on the take as a user holds it (scan,
marker take, JSON map), compared with the truth by
:func:`~facecap.report.evaluate_performance.evaluate_performance` (mean over all vertices and
frames, mm; an unstabilised result against the truth moved by the head motion).

Rows, per case:

- ``oracle``; ``today``: ``marker_offset_mm=0, rest_average_s=0, temporal_sigma_s=0.02`` (the
  markers taken to lie on the skin, the warp's rest the rest frame alone, the filter's fixed
  window: what animate did before this item), and without a head band the most rigid set of skin
  markers as the head pose (:func:`stabiliser_before_2026_12_04`: ``auto_stabilize`` before the
  consensus became its choice), so that ``today`` stays the issue's baseline;
  ``offset``: only the offset (warp onto the lifted scan points, offset carried with the surface);
  ``rest avg``: only the averaged rest; ``sigma cv``: only the filter's temporal sigma chosen for the
  take by cross-validation (``temporal_sigma_s='auto'``); ``offset + rest avg``: the defaults of
  the release before the cross-validated sigma; ``new, rigid set``: all three with the stabiliser of
  ``today``; ``new``: the defaults (all three, and the consensus head pose without a head band).
- Switch-offs, each re-generating the take with one cause removed (same seed, so the same
  everything else), run ``today`` and ``new``: ``noise 0`` (``noise_mm=0``), ``offset 0``
  (``marker_offset_mm=0``), ``gaps 0`` (``gap_fraction=0``), ``head still`` (no head rotation or
  translation; still stabilised, as a user would), and ``true head`` (the generator's head
  motion removed from the markers, ``stabilize`` off: a perfect stabiliser).
- ``--what-if``: two rows for levers outside ``animate``: ``new`` with the bilateral filter's
  temporal sigma at 0.06 s instead of 0.02 s (``filter 0.06``), and the same with the true head
  motion removed (``filter 0.06, true head``). They run animate's steps in memory
  (:func:`~facecap.markers.prepare_take.prepare_markers` with ``smooth=False``, then
  :func:`~facecap.markers.bilateral_filter.bilateral_filter`, the averaged rest, the lifted
  warp, :class:`~facecap.deform.marker_offsets.MarkerOffsets`, the shell); with the default
  filter these steps give ``new`` to 0.001 mm.
- ``closed``: ``(today - new) / (today - oracle)``; a switch-off's share is
  ``(today - today_off) / (today - oracle)`` (shares need not add up: the causes interact).

Run (about 1-2 minutes per case on 2 cores)::

    python benchmarks/bench_marker_offsets.py --set tuned
    python benchmarks/bench_marker_offsets.py --set held-out      # once, for the report
    python benchmarks/bench_marker_offsets.py --speed             # per-frame cost at 100k vertices
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

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from cases import HELD_OUT_CASES, TUNED_CASES, Case, make_case  # noqa: E402

from facecap.markers.prepare_take import DEFAULT_REST_AVERAGE_S, prepare_markers  # noqa: E402
from facecap.pipelines.animate_scan import animate_scan  # noqa: E402
from facecap.deform.triharmonic_warp import TriharmonicWarp  # noqa: E402
from facecap.markers.bilateral_filter import bilateral_filter  # noqa: E402
from facecap.deform.marker_offsets import MarkerOffsets  # noqa: E402
from facecap.deform.thin_shell import ThinShellSolver  # noqa: E402
from facecap.errors import FacecapWarning  # noqa: E402
from facecap.io.read_correspondence import read_correspondence  # noqa: E402
from facecap.report.evaluate_performance import evaluate_performance  # noqa: E402
from facecap.synth.generate_performance import SyntheticCase  # noqa: E402

N_FRAMES = 600
TODAY = {"marker_offset_mm": 0.0, "rest_average_s": 0.0, "temporal_sigma_s": 0.02}  # animate before issue 9
FIXED_SIGMA = {"temporal_sigma_s": 0.02}
METHODS = {"today": TODAY, "offset": {"rest_average_s": 0.0, **FIXED_SIGMA},
           "rest avg": {"marker_offset_mm": 0.0, **FIXED_SIGMA}, "sigma cv": {"marker_offset_mm": 0.0, "rest_average_s": 0.0},
           "offset + rest avg": FIXED_SIGMA, "new, rigid set": {}, "new": {}}
SWITCH_OFFS: dict[str, dict[str, Any]] = {
    "noise 0": {"noise_mm": 0.0},
    "offset 0": {"marker_offset_mm": 0.0},
    "gaps 0": {"gap_fraction": 0.0},
    "head still": {"head_rotation_deg": 0.0, "head_translation_mm": 0.0},
}


OLD_STABILISER = ("today", "new, rigid set")
"""Rows run with :func:`stabiliser_before_2026_12_04` (with every switch-off's ``today``)."""


@contextlib.contextmanager
def stabiliser_before_2026_12_04() -> Iterator[None]:
    """``animate``'s automatic stabiliser as it was before 2026-12-04: without a rigid head band, the most rigid set.

    Since then :func:`~facecap.markers.condition_take.auto_stabilize` returns the consensus of the skin
    markers instead of that set; ``skin_head_pose='rigid_set'`` restores the set, and the head band's
    test and the still-head test are those of the earlier release.
    """
    condition = importlib.import_module("facecap.markers.condition_take")
    current = condition.auto_stabilize

    def before(P: np.ndarray, rest_frame: int, preferred: Any, **_: Any) -> Any:
        return current(P, rest_frame, preferred, skin_head_pose="rigid_set")

    condition.auto_stabilize = before
    try:
        yield
    finally:
        condition.auto_stabilize = current


def oracle_error(synthetic: SyntheticCase) -> float:
    """Mean dense error of the shell driven by the exact skin displacements (mm)."""
    V, F, mv = synthetic.scan.vertices, synthetic.scan.faces, synthetic.marker_vertices
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FacecapWarning)
        solver = ThinShellSolver(V, F, mv)
    truth = synthetic.truth_vertices
    result = V.astype(np.float32)[None] + solver.displacements(truth[:, mv] - V[mv].astype(np.float32))
    return evaluate_performance(result, truth).mean_mm


def without_head_motion(synthetic: SyntheticCase):
    """The take with the generator's head motion removed (markers in the rest frame's head pose)."""
    M = synthetic.mocap_from_scan
    S = M[None] @ np.linalg.inv(synthetic.head_pose) @ np.linalg.inv(M)[None]
    P = np.einsum("tij,tkj->tki", S[:, :3, :3], synthetic.markers.positions) + S[:, None, :3, 3]
    return synthetic.markers.with_positions(P)


def animate_error(synthetic: SyntheticCase, folder: Path, *, markers=None, stabilize: bool = True,
                  **options: Any) -> float:
    """Mean dense error of ``animate_scan`` on the take (mm)."""
    scan = synthetic.scan
    map_path = folder / "map.json"
    map_path.write_text(json.dumps(synthetic.correspondence))
    out = folder / "result"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FacecapWarning)
        corr = read_correspondence(map_path, scan)
        animate_scan(scan, synthetic.markers if markers is None else markers, corr, out,
                     stabilize=stabilize, progress=False, **options)
    result = np.load(out / "vertices.npy", mmap_mode="r")
    truth = synthetic.truth_vertices
    stabilized = json.loads((out / "performance.json").read_text())["stabilized"]  # auto leaves a still head
    if not stabilized and markers is None:
        pose = synthetic.head_pose
        truth = (np.einsum("tij,tnj->tni", pose[:, :3, :3].astype(np.float32), truth)
                 + pose[:, None, :3, 3].astype(np.float32))
    return evaluate_performance(result, truth).mean_mm


def what_if_error(synthetic: SyntheticCase, folder: Path, *, temporal_sigma_s: float, true_head: bool) -> float:
    """``new`` with another temporal sigma of the bilateral filter, animate's steps run in memory (mm)."""
    animate_module = importlib.import_module("facecap.pipelines.animate_scan")  # its rest average

    map_path = folder / "map.json"
    map_path.write_text(json.dumps(synthetic.correspondence))
    markers = without_head_motion(synthetic) if true_head else synthetic.markers
    V, F = synthetic.scan.vertices, synthetic.scan.faces
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FacecapWarning)
        corr = read_correspondence(map_path, synthetic.scan)
        prepared = prepare_markers(markers, synthetic.scan, corr, stabilize=not true_head, smooth=False)
        P = bilateral_filter(prepared.positions, rate=markers.rate, temporal_sigma_s=temporal_sigma_s)
        solver = ThinShellSolver(V, F, prepared.constrained_vertices)
    offsets = MarkerOffsets(V, F, solver)
    rest = animate_module.rest_average(P, 0, DEFAULT_REST_AVERAGE_S * markers.rate)
    centres = prepared.scan_points + offsets.marker_offset_mm * offsets.rest_normals
    D = TriharmonicWarp(rest, centres)(P) - centres[None]
    result = V.astype(np.float32)[None] + solver.displacements(offsets.skin_displacements(D))
    return evaluate_performance(result, synthetic.truth_vertices).mean_mm


def run_case(case: Case, n_frames: int, what_if: bool = False) -> dict[str, float]:
    """Every row of the table for one case."""
    row: dict[str, float] = {}
    synthetic = make_case(case, n_frames=n_frames)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        row["oracle"] = oracle_error(synthetic)
        for name, options in METHODS.items():
            with stabiliser_before_2026_12_04() if name in OLD_STABILISER else contextlib.nullcontext():
                row[name] = animate_error(synthetic, folder, **options)
        for name, change in SWITCH_OFFS.items():
            generator = {**case.generator, **change}
            off = make_case(Case(case.name, case.held_out, generator, case.curves), n_frames=n_frames)
            with stabiliser_before_2026_12_04():
                row[f"{name}: today"] = animate_error(off, folder, **TODAY)
            row[f"{name}: new"] = animate_error(off, folder)
        still = without_head_motion(synthetic)
        row["true head: today"] = animate_error(synthetic, folder, markers=still, stabilize=False, **TODAY)
        row["true head: new"] = animate_error(synthetic, folder, markers=still, stabilize=False)
        if what_if:
            row["what-if: filter 0.06"] = what_if_error(synthetic, folder, temporal_sigma_s=0.06, true_head=False)
            row["what-if: filter 0.06, true head"] = what_if_error(synthetic, folder, temporal_sigma_s=0.06,
                                                                   true_head=True)
    return row


def table(rows: dict[str, dict[str, float]]) -> str:
    """Markdown: one column per case, then the median; errors in mm, shares of today's gap in %."""
    names = list(rows)
    keys = list(next(iter(rows.values())))
    out = ["| row | " + " | ".join(names) + " | median |", "|---|" + "---|" * (len(names) + 1)]

    def line(label: str, values: list[float], fmt: str) -> str:
        return f"| {label} | " + " | ".join(fmt.format(v) for v in values) + " | " + fmt.format(statistics.median(values)) + " |"

    for k in keys:
        out.append(line(k, [rows[n][k] for n in names], "{:.3f}"))
    gap = {n: rows[n]["today"] - rows[n]["oracle"] for n in names}
    out.append(line("gap today - oracle (mm)", [gap[n] for n in names], "{:.3f}"))
    closers = ["offset", "rest avg", "new, rigid set", "new"] + [k for k in keys if k.startswith("what-if")]
    for k in closers:
        out.append(line(f"closed by {k} (%)", [100 * (rows[n]["today"] - rows[n][k]) / gap[n] for n in names], "{:.0f}"))
    for k in [*SWITCH_OFFS, "true head"]:
        out.append(line(f"share of {k} (%)", [100 * (rows[n]["today"] - rows[n][f"{k}: today"]) / gap[n] for n in names], "{:.0f}"))
    return "\n".join(out)


def speed(case_name: str, n_frames: int, repeats: int) -> None:
    """Per-frame cost of the offset correction against the shell product, on a benchmark mesh."""
    import _meshes

    mesh = _meshes.bench_mesh(case_name)
    V, F = mesh.V, mesh.F
    markers = _meshes.farthest_point_markers(V, 90)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FacecapWarning)
        solver = ThinShellSolver(V, F, markers)
    t = time.perf_counter()
    offsets = MarkerOffsets(V, F, solver)
    setup = time.perf_counter() - t
    rng = np.random.default_rng(0)
    D = rng.normal(scale=2.0, size=(n_frames, markers.size, 3))
    rest = V.astype(np.float32)
    out = np.empty((32, V.shape[0], 3), np.float32)
    D32 = D[:32].astype(np.float32)

    def best(fn) -> float:
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
        return min(times)

    correction = best(lambda: offsets.skin_displacements(D)) / n_frames
    shell = best(lambda: [solver.deform_into(D32, rest, out) for _ in range(max(1, n_frames // 32))]) / (32 * max(1, n_frames // 32))
    print(f"{case_name}: {V.shape[0]} vertices, {markers.size} markers, ring {offsets.ring_vertices.size} vertices; "
          f"set-up {setup:.2f} s; correction {1e6 * correction:.1f} us/frame ({offsets.iterations} steps), "
          f"shell product {1e6 * shell:.1f} us/frame (batch 32): {100 * correction / shell:.1f} %")


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--set", choices=("tuned", "held-out"), default="tuned")
    p.add_argument("--only", default=None, help="comma-separated case names")
    p.add_argument("--frames", type=int, default=N_FRAMES)
    p.add_argument("--save", default=None, help="raw figures as JSON")
    p.add_argument("--what-if", action="store_true", help="add the rows of a stronger temporal filter")
    p.add_argument("--speed", default=None, metavar="MESH", help="time the correction on a benchmarks/_meshes case (e.g. 100k)")
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args(argv)
    if args.speed:
        speed(args.speed, args.frames, args.repeats)
        return
    cases = TUNED_CASES if args.set == "tuned" else HELD_OUT_CASES
    if args.only:
        wanted = set(args.only.split(","))
        cases = tuple(c for c in cases if c.name in wanted)
    rows: dict[str, dict[str, float]] = {}
    for case in cases:
        t = time.perf_counter()
        rows[case.name] = run_case(case, args.frames, args.what_if)
        print(f"{case.name}: " + ", ".join(f"{k} {v:.3f}" for k, v in rows[case.name].items())
              + f" ({time.perf_counter() - t:.0f} s)", file=sys.stderr, flush=True)
    if args.save:
        Path(args.save).write_text(json.dumps(rows, indent=1))
    print(table(rows))


if __name__ == "__main__":
    main()
