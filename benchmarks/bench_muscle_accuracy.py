"""Issue 11's real-take bars: the muscle solve against ``animate`` on the same takes.

Bars measured (issue 11):

- **Leave markers out**: hold markers out of the solve, predict their motion from the skin; the
  error is at most 1.1x that of ``facecap animate`` on the same take. Also the marker residual and,
  on generated takes, the dense error against the truth beside ``animate``'s.
- **Robustness** (the paper's Fig. 7): one marker displaced 5 mm for a few frames moves the skin
  round it at most a third as much as it moves ``animate``'s result.

Run (one core a run; 8-17 minutes a case at the default model size, most of it the muscle solves)::

    python benchmarks/bench_muscle_accuracy.py --set tuned            # AnimFace + 2 tuned generated takes
    python benchmarks/bench_muscle_accuracy.py --set held-out         # once, for the report
    python benchmarks/bench_muscle_accuracy.py --quick                # AnimFace only, small: a smoke run

Protocol
--------
Every take is conditioned once, with all its markers, as ``animate`` conditions a take
(:func:`facecap.markers.prepare_markers`: matched, gap-filled, stabilised, the bilateral filter with
its temporal sigma chosen per take). The conditioned markers are then the input of both methods,
frame for frame (``smooth=False``, ``stabilize=False`` from there on), so neither sees anything
the other does not:

- ``animate``: :func:`facecap.pipelines.animate_scan` (the warp, the marker offsets, the thin shell);
- muscles: :func:`facecap.pipelines.solve_muscle_take` with ``retarget='warp'``, so its markers reach
  the face by the same triharmonic warp from the same rest markers (``rest_average``) onto the same
  lifted map points: the difference is the face model alone. One runner chunk (only the first frame
  solved from rest), in this process. The model is ``build_anatomy`` of the take's scan at
  ``--tets``.

To keep the muscle solve's cost bounded, every ``--stride``-th frame of the conditioned take is used
(at most ``--frames`` of them) as a take at the lower rate; both methods get the same frames.

**Leave markers out.** Markers on the model (the ones the muscle solve can carry) are spread by
farthest-point sampling and dealt into ``--groups`` groups of ``--group-size``, so that a group's
markers are far apart (default 4 groups of 3, 12 markers per take; ``--group-size 1`` is the strict
leave-one-out at four times the cost). For each group both methods run without the group's markers
(map and take). At a held-out marker ``i`` the predicted motion is that of the marker's point on the
result's skin, lifted by the marker height along the result's normal, from its rest position
(the scan's point, lifted the same way); the reference is ``i``'s observed motion through the warp of
the markers left in, ``c_G(p_i(t)) - c_G(rest_i)`` (the protocol of ``bench_accuracy.py``, with the
warp both methods used). Reported: mean and 95th percentile over held-out markers and frames, and
the ratio muscles / animate of the means (the bar: <= 1.1).

**Dense error** (generated takes): the full run (all markers) of each method against
``truth_vertices`` at every scan vertex the muscle model's mesh carries (the narrow face), mean over
vertices and frames; the marker residual of the muscle solve from its ``report.json``.

**Robustness.** A window of ``--window`` frames at the take's own rate where the markers move most
(after the take's rest frame, which both methods need as their rest); in its middle
``--glitch-frames`` frames of one marker moved by 5 mm in a fixed random direction (three markers,
one at a time: the centre of the face, and the two markers farthest from it and each other). Both
methods run on the clean and the displaced window; the skin's change is the mean over the displaced
frames and the scan vertices within ``--radius`` mm of the marker's point of ``|x_glitch - x_clean|``.
Bar: muscles / animate <= 1/3, per marker and on the mean.

The held-out cases are ``benchmarks/cases.py``'s ``HELD_OUT_CASES`` (never looked at while tuning);
the AnimFace take has no truth, so it gives the leave-markers-out and robustness figures only.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from cases import HELD_OUT_CASES, TUNED_CASES, Case, make_case  # noqa: E402

from facecap.anatomy import build_anatomy, load_anatomy  # noqa: E402
from facecap.markers.prepare_take import DEFAULT_REST_AVERAGE_S, prepare_markers, rest_average  # noqa: E402
from facecap.pipelines.animate_scan import animate_scan  # noqa: E402
from facecap.deform.marker_offsets import DEFAULT_MARKER_OFFSET_MM, marker_ring  # noqa: E402
from facecap.deform.thin_shell import ThinShellSolver  # noqa: E402
from facecap.deform.triharmonic_warp import TriharmonicWarp  # noqa: E402
from facecap.errors import FacecapWarning  # noqa: E402
from facecap.io.read_correspondence import read_correspondence  # noqa: E402
from facecap.io.read_markers import read_markers  # noqa: E402
from facecap.pipelines import solve_muscle_take  # noqa: E402
from facecap.structures import MarkerSequence, Mesh  # noqa: E402
from facecap.io.ict_sample import bundled_path, load_ict_sample  # noqa: E402

TUNED = ("default_0", "studio_a_real")
HELD_OUT = ("held_real_turns", "held_speech_turns", "held_real_still")
LOO_BAR = 1.1
ROBUSTNESS_BAR = 1.0 / 3.0
GLITCH_MM = 5.0
RESIDUAL_MEDIAN_S = 0.15


def residual_correction(V: np.ndarray, observed: np.ndarray, take: "Take", rows: np.ndarray, rest: np.ndarray,
                        basis: np.ndarray, rate: float, *, vertices: np.ndarray | None = None) -> np.ndarray:
    """A candidate layer over the muscle face (not the package's): the markers' residual motion, temporally
    median-filtered (``RESIDUAL_MEDIAN_S``: a glitch of fewer frames than half the window is dropped), carried to
    the skin by the thin shell of those markers. Returns the correction at ``vertices`` (all by default), (T, n, 3).

    ``observed`` (T, k, 3): the markers' observed motion in face space (through the warp, from rest); the model's
    own is its skin's, at the markers' points lifted along its normals (``rest``: the same at rest).
    """
    from scipy.ndimage import median_filter

    model = _marker_points(V, take.scan.faces, take.corr, rows, DEFAULT_MARKER_OFFSET_MM) - rest[None]
    residual = observed - model
    width = max(1, int(round(RESIDUAL_MEDIAN_S * rate))) | 1
    if width > 1:
        residual = median_filter(residual, size=(width, 1, 1), mode="nearest")
    B = basis if vertices is None else basis[:, vertices]
    return np.einsum("kn,tkc->tnc", B.astype(np.float64), residual)


SOLVER_OPTIONS: dict[str, Any] = {}
"""``solve_muscle_take(solver_options=...)`` of every muscle run (``--solver-options``)."""


def quiet(function: Any, *args: Any, **kwargs: Any) -> Any:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FacecapWarning)
        return function(*args, **kwargs)


class Take:
    """A conditioned take with its scan, map, model folder and (generated) truth."""

    def __init__(self, name: str, held_out: bool, scan: Mesh, markers: MarkerSequence, map_path: Path,
                 truth: np.ndarray | None, work: Path, n_tets: int) -> None:
        self.name, self.held_out, self.scan, self.work = name, held_out, scan, work
        self.map_path = map_path
        corr = read_correspondence(map_path, scan)
        self.prepared = quiet(prepare_markers, markers, scan, corr, stabilize=True)
        self.corr = corr.select(list(self.prepared.labels))
        self.rate = markers.rate
        # the rest markers as animate takes them (the Gaussian average round the rest frame, at the take's rate);
        # every sequence below starts with them and both methods then take that frame alone (rest_average_s=0)
        self.rest = rest_average(self.prepared.positions, 0, DEFAULT_REST_AVERAGE_S * self.rate)
        vertices = self.corr.vertex_indices[np.arange(len(self.corr)), np.argmax(self.corr.weights, axis=1)]
        self.lifted = self.corr.points(scan.vertices) + DEFAULT_MARKER_OFFSET_MM * marker_ring(
            scan.vertices, scan.faces, vertices).rest_normals
        self.vertices = vertices
        self.truth = truth
        model = work / f"model_{name}_{n_tets}"
        if not (model / "anatomy.json").is_file():
            t = time.perf_counter()
            build_anatomy(scan, n_tets=n_tets, progress=False).save(model)
            print(f"  {name}: anatomy built in {time.perf_counter() - t:.0f} s", file=sys.stderr)
        self.model = model
        anatomy = load_anatomy(model)
        vertices = self.corr.vertex_indices[np.arange(len(self.corr)), np.argmax(self.corr.weights, axis=1)]
        on_model = np.asarray(anatomy.skin_meshed)[vertices] & (np.abs(np.asarray(anatomy.skin_weights)[vertices])
                                                                 .max(axis=1) <= 3.0)
        self.on_model = on_model
        self.face_vertices = np.flatnonzero(np.asarray(anatomy.skin_meshed))

    def correction(self, V: np.ndarray, positions: np.ndarray, rate: float) -> np.ndarray:
        """The candidate residual layer (:func:`residual_correction`) over a muscle result of all markers."""
        if not hasattr(self, "_basis"):
            self._basis = quiet(ThinShellSolver, self.scan.vertices, self.scan.faces, self.vertices).basis
        warp = TriharmonicWarp(self.rest, self.lifted)
        rows = np.arange(len(self.corr))
        rest = _marker_points(self.scan.vertices[None], self.scan.faces, self.corr, rows, DEFAULT_MARKER_OFFSET_MM)[0]
        return residual_correction(V, warp(positions) - self.lifted[None], self, rows, rest, self._basis, rate)

    def frames(self, stride: int, n: int) -> np.ndarray:
        return np.arange(0, self.prepared.positions.shape[0], stride)[:n]

    def sequence(self, frames: np.ndarray, rate: float, *, without: tuple[int, ...] = (),
                 positions: np.ndarray | None = None) -> tuple[MarkerSequence, Path]:
        """The conditioned markers at ``frames`` (less the ``without`` columns) as a take, and its map."""
        P = (self.prepared.positions[frames] if positions is None else positions).copy()
        if frames[0] == 0:
            P[0] = self.rest
        keep = np.setdiff1d(np.arange(P.shape[1]), without)
        labels = tuple(self.prepared.labels[i] for i in keep)
        seq = MarkerSequence(np.ascontiguousarray(P[:, keep]), labels, rate=rate)
        doc = json.loads(self.map_path.read_text())
        path = self.work / f"map_{self.name}_{'-'.join(map(str, without)) or 'all'}.json"
        path.write_text(json.dumps({k: doc[k] for k in labels}))
        return seq, path

    def run_animate(self, seq: MarkerSequence, map_path: Path, tag: str) -> np.ndarray:
        out = self.work / f"animate_{tag}"
        shutil.rmtree(out, ignore_errors=True)
        corr = read_correspondence(map_path, self.scan)
        quiet(animate_scan, self.scan, seq, corr, out, stabilize=False, smooth=False, rest_average_s=0.0, progress=False)
        V = np.load(out / "vertices.npy").astype(np.float64)
        shutil.rmtree(out, ignore_errors=True)
        return V

    def run_muscles(self, seq: MarkerSequence, map_path: Path, tag: str) -> tuple[np.ndarray, dict[str, Any]]:
        out = self.work / f"muscles_{tag}"
        shutil.rmtree(out, ignore_errors=True)
        done = quiet(solve_muscle_take, self.model, seq, map_path, out, retarget="warp", stabilize=False,
                     rest_average_s=0.0, smooth=False, scheduler="synchronous", chunk_frames=seq.n_frames,
                     solver_options=SOLVER_OPTIONS)
        V = np.load(out / "vertices.npy").astype(np.float64)
        shutil.rmtree(out, ignore_errors=True)
        return V, done.report


def _marker_points(V: np.ndarray, faces: np.ndarray, corr: Any, rows: np.ndarray, height: float) -> np.ndarray:
    """Markers ``rows`` of the map on skin frames ``V`` (T, n, 3): the barycentric point lifted along the normal."""
    T = V.shape[0]
    out = np.empty((T, rows.size, 3))
    for t in range(T):
        fn = np.cross(V[t, faces[:, 1]] - V[t, faces[:, 0]], V[t, faces[:, 2]] - V[t, faces[:, 0]])
        vn = np.zeros_like(V[t])
        for c in range(3):
            np.add.at(vn, faces[:, c], fn)
        vn /= np.maximum(np.linalg.norm(vn, axis=1, keepdims=True), 1e-300)
        idx, w = corr.vertex_indices[rows], corr.weights[rows]
        p = np.einsum("kj,kjc->kc", w, V[t][idx])
        n = np.einsum("kj,kjc->kc", w, vn[idx])
        out[t] = p + height * n / np.linalg.norm(n, axis=1, keepdims=True)
    return out


def _spread_groups(points: np.ndarray, candidates: np.ndarray, n_groups: int, size: int) -> list[tuple[int, ...]]:
    """``n_groups`` groups of ``size`` candidate markers, each group's markers far apart (farthest points dealt)."""
    chosen = [int(candidates[np.argmin(np.linalg.norm(points[candidates] - points[candidates].mean(0), axis=1))])]
    while len(chosen) < min(n_groups * size, candidates.size):
        d = np.min(np.linalg.norm(points[candidates][:, None] - points[chosen][None], axis=2), axis=1)
        chosen.append(int(candidates[np.argmax(d)]))
    return [tuple(sorted(chosen[g::n_groups])) for g in range(n_groups)]


def leave_markers_out(take: Take, frames: np.ndarray, rate: float, groups: list[tuple[int, ...]]) -> dict[str, Any]:
    P = take.prepared.positions[frames].copy()
    P[0] = take.rest
    K = P.shape[1]
    sources, lifted = take.rest, take.lifted
    vertices = take.corr.vertex_indices[np.arange(K), np.argmax(take.corr.weights, axis=1)]
    faces = take.scan.faces
    errors: dict[str, list[np.ndarray]] = {"animate": [], "muscles": [], "muscles+residual shell": []}
    per_marker = []
    for g, group in enumerate(groups):
        others = np.setdiff1d(np.arange(K), group)
        warp = TriharmonicWarp(sources[others], lifted[others])
        rows = np.asarray(group)
        reference = warp(P[:, rows]) - warp(sources[rows])[None]  # (T, g, 3)
        seq, map_path = take.sequence(frames, rate, without=group)
        t0 = time.perf_counter()
        V_animate = take.run_animate(seq, map_path, f"loo{g}")
        t1 = time.perf_counter()
        V_muscles, _ = take.run_muscles(seq, map_path, f"loo{g}")
        t2 = time.perf_counter()
        rest = _marker_points(take.scan.vertices[None], faces, take.corr, rows, DEFAULT_MARKER_OFFSET_MM)[0]
        for name, V in (("animate", V_animate), ("muscles", V_muscles)):
            predicted = _marker_points(V, faces, take.corr, rows, DEFAULT_MARKER_OFFSET_MM) - rest[None]
            errors[name].append(np.linalg.norm(predicted - reference, axis=2))  # (T, g)
        # the candidate layer: the muscle face plus the shell of the other markers' residuals
        rest_o = _marker_points(take.scan.vertices[None], faces, take.corr, others, DEFAULT_MARKER_OFFSET_MM)[0]
        observed_o = warp(P[:, others]) - warp(sources[others])[None]
        basis = quiet(ThinShellSolver, take.scan.vertices, faces, vertices[others]).basis
        support = np.unique(take.corr.vertex_indices[rows])
        correction = residual_correction(V_muscles, observed_o, take, others, rest_o, basis, rate, vertices=support)
        V_hybrid = V_muscles.copy()
        V_hybrid[:, support] += correction
        predicted = _marker_points(V_hybrid, faces, take.corr, rows, DEFAULT_MARKER_OFFSET_MM) - rest[None]
        errors["muscles+residual shell"].append(np.linalg.norm(predicted - reference, axis=2))
        for j, i in enumerate(group):
            per_marker.append({"label": take.prepared.labels[i],
                               "animate_mean_mm": float(errors["animate"][-1][:, j].mean()),
                               "muscles_mean_mm": float(errors["muscles"][-1][:, j].mean()),
                               "hybrid_mean_mm": float(errors["muscles+residual shell"][-1][:, j].mean()),
                               "motion_rms_mm": float(np.sqrt((reference[:, j] ** 2).sum(1).mean()))})
        print(f"  {take.name}: group {g + 1}/{len(groups)} {[take.prepared.labels[i] for i in group]}: animate "
              f"{errors['animate'][-1].mean():.3f} mm ({t1 - t0:.0f} s), muscles {errors['muscles'][-1].mean():.3f} "
              f"mm ({t2 - t1:.0f} s), muscles+residual shell {errors['muscles+residual shell'][-1].mean():.3f} mm",
              file=sys.stderr)
    stats = {}
    for name, values in errors.items():
        a = np.concatenate([v.ravel() for v in values])
        stats[name] = {"mean_mm": float(a.mean()), "p95_mm": float(np.percentile(a, 95))}
    stats["ratio"] = stats["muscles"]["mean_mm"] / stats["animate"]["mean_mm"]
    stats["hybrid_ratio"] = stats["muscles+residual shell"]["mean_mm"] / stats["animate"]["mean_mm"]
    stats["muscles_better_markers"] = sum(m["muscles_mean_mm"] <= m["animate_mean_mm"] for m in per_marker)
    stats["held_out_markers"] = len(per_marker)
    stats["per_marker"] = per_marker
    return stats


def dense_and_residual(take: Take, frames: np.ndarray, rate: float) -> dict[str, Any]:
    seq, map_path = take.sequence(frames, rate)
    t0 = time.perf_counter()
    V_animate = take.run_animate(seq, map_path, "full")
    t1 = time.perf_counter()
    V_muscles, report = take.run_muscles(seq, map_path, "full")
    t2 = time.perf_counter()
    V_hybrid = V_muscles + take.correction(V_muscles, seq.positions, rate)
    out: dict[str, Any] = {
        "muscle_marker_rms_mm": report["marker_residual_mm"]["rms"],
        "muscle_marker_max_mm": report["marker_residual_mm"]["max"],
        "frames_flagged": report["frames_flagged"], "flags": report["flags"],
        "inverted_tets_max": int(max(report["inverted_tets"])),
        "constraint_violation_max": report["constraint_violation_max"],
        "markers_left_out": report.get("markers_left_out", []),
        "seconds": {"animate": t1 - t0, "muscles": t2 - t1},
        "muscle_s_per_frame": (t2 - t1) / len(frames),
    }
    if take.truth is not None:
        truth = np.asarray(take.truth[frames], np.float64)[:, take.face_vertices]
        for name, V in (("animate", V_animate), ("muscles", V_muscles), ("hybrid", V_hybrid)):
            e = np.linalg.norm(V[:, take.face_vertices] - truth, axis=2)
            out[f"dense_{name}_mean_mm"] = float(e.mean())
            out[f"dense_{name}_p95_mm"] = float(np.percentile(e, 95))
        out["dense_ratio"] = out["dense_muscles_mean_mm"] / out["dense_animate_mean_mm"]
        out["dense_hybrid_ratio"] = out["dense_hybrid_mean_mm"] / out["dense_animate_mean_mm"]
    return out


def robustness(take: Take, window: int, glitch_frames: int, radius: float, seed: int) -> dict[str, Any]:
    P_all = take.prepared.positions
    T = P_all.shape[0]
    # the window where the face moves most (a glitch on a still face is the easy case)
    motion = np.linalg.norm(P_all - P_all[:1], axis=2).mean(axis=1)
    start = int(np.clip(np.argmax(motion) - window // 2, 1, T - window))
    frames = np.concatenate([[0], np.arange(start, start + window)])  # the rest frame first: the warp's rest
    P = P_all[frames]
    candidates = np.flatnonzero(take.on_model)
    points = take.corr.points(take.scan.vertices)
    centre = candidates[np.argmin(np.linalg.norm(points[candidates] - points[candidates].mean(0), axis=1))]
    far1 = candidates[np.argmax(np.linalg.norm(points[candidates] - points[centre], axis=1))]
    far2 = candidates[np.argmax(np.minimum(np.linalg.norm(points[candidates] - points[centre], axis=1),
                                           np.linalg.norm(points[candidates] - points[far1], axis=1)))]
    rng = np.random.default_rng(seed)
    seq, map_path = take.sequence(frames, take.rate)
    clean = {"animate": take.run_animate(seq, map_path, "clean"), "muscles": take.run_muscles(seq, map_path, "clean")[0]}
    clean["hybrid"] = clean["muscles"] + take.correction(clean["muscles"], seq.positions, take.rate)
    glitch = 1 + np.arange(window // 2 - glitch_frames // 2, window // 2 - glitch_frames // 2 + glitch_frames)
    rows = []
    for j in (centre, far1, far2):
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        Q = P.copy()
        Q[glitch, j] += GLITCH_MM * direction
        seq_g, _ = take.sequence(frames, take.rate, positions=Q)
        moved = {"animate": take.run_animate(seq_g, map_path, "glitch"),
                 "muscles": take.run_muscles(seq_g, map_path, "glitch")[0]}
        moved["hybrid"] = moved["muscles"] + take.correction(moved["muscles"], seq_g.positions, take.rate)
        near = np.flatnonzero(np.linalg.norm(take.scan.vertices - points[j], axis=1) <= radius)
        row = {"label": take.prepared.labels[int(j)], "vertices_within_radius": int(near.size)}
        for name in ("animate", "muscles", "hybrid"):
            change = np.linalg.norm(moved[name][glitch][:, near] - clean[name][glitch][:, near], axis=2)
            row[f"{name}_mean_mm"] = float(change.mean())
            row[f"{name}_max_mm"] = float(change.max())
        row["ratio"] = row["muscles_mean_mm"] / row["animate_mean_mm"]
        row["hybrid_ratio"] = row["hybrid_mean_mm"] / row["animate_mean_mm"]
        rows.append(row)
        print(f"  {take.name}: glitch on {row['label']}: animate {row['animate_mean_mm']:.3f} mm, muscles "
              f"{row['muscles_mean_mm']:.3f} mm (ratio {row['ratio']:.3f}), hybrid {row['hybrid_mean_mm']:.3f} mm",
              file=sys.stderr)
    mean_ratio = float(np.mean([r["muscles_mean_mm"] for r in rows]) / np.mean([r["animate_mean_mm"] for r in rows]))
    return {"window": [int(frames[1]), int(frames[-1]) + 1], "glitch_frames": glitch.tolist(), "radius_mm": radius,
            "markers": rows, "ratio_of_means": mean_ratio, "worst_ratio": max(r["ratio"] for r in rows),
            "hybrid_worst_ratio": max(r["hybrid_ratio"] for r in rows)}


def load_take(name: str, work: Path, n_tets: int, n_frames: int) -> Take:
    if name == "animface":
        sample = load_ict_sample()
        return Take("animface", False, sample.mesh, read_markers(bundled_path("eyebrows.c3d")),
                    bundled_path("ict_generic_map.json"), None, work, n_tets)
    case: Case = next(c for c in TUNED_CASES + HELD_OUT_CASES if c.name == name)
    synthetic = make_case(case, n_frames=n_frames)
    map_path = work / f"map_{name}.json"
    map_path.write_text(json.dumps({k: int(v) for k, v in synthetic.correspondence.items()}))
    return Take(name, case.held_out, synthetic.scan, synthetic.markers, map_path, synthetic.truth_vertices, work,
                n_tets)


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}"


def markdown(results: list[dict[str, Any]], args: argparse.Namespace) -> str:
    lines = [f"Machine: {machine()}. Model: `build_anatomy(scan, n_tets={args.tets})`; every {args.stride}th frame "
             f"(at most {args.frames}); {args.groups} groups of {args.group_size} markers held out per take.", "",
             "| take | set | held out | animate mean / p95 (mm) | muscles mean / p95 (mm) | ratio (bar 1.1) | "
             "muscles better at | +residual shell ratio | dense animate / muscles / +shell (mm) | muscle marker rms "
             "(mm) | glitch ratio worst / of means (bar 0.33) | +shell glitch worst | s per frame |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        L, D, R = r["leave_markers_out"], r["full"], r["robustness"]
        dense = (f"{D['dense_animate_mean_mm']:.3f} / {D['dense_muscles_mean_mm']:.3f} / {D['dense_hybrid_mean_mm']:.3f}"
                 if "dense_animate_mean_mm" in D else "no truth")
        lines.append(
            f"| {r['name']} | {'held out' if r['held_out'] else 'tuned'} | {L['held_out_markers']} | "
            f"{L['animate']['mean_mm']:.3f} / {L['animate']['p95_mm']:.3f} | {L['muscles']['mean_mm']:.3f} / "
            f"{L['muscles']['p95_mm']:.3f} | **{L['ratio']:.2f}** | {L['muscles_better_markers']}/"
            f"{L['held_out_markers']} | {L['hybrid_ratio']:.2f} | {dense} | {D['muscle_marker_rms_mm']:.3f} | "
            f"{R['worst_ratio']:.3f} / {R['ratio_of_means']:.3f} | {R['hybrid_worst_ratio']:.3f} | "
            f"{D['muscle_s_per_frame']:.2f} |")
    return "\n".join(lines) + "\n"


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--set", choices=("tuned", "held-out", "all"), default="tuned")
    p.add_argument("--cases", default=None, help="comma-separated case names (animface, benchmarks/cases.py names)")
    p.add_argument("--tets", type=int, default=20000, help="build_anatomy's n_tets [20000: about 21k tetrahedra]")
    p.add_argument("--stride", type=int, default=8, help="every STRIDE-th conditioned frame [8]")
    p.add_argument("--frames", type=int, default=75, help="at most this many of them [75]")
    p.add_argument("--generated-frames", type=int, default=600, help="frames of a generated take [600]")
    p.add_argument("--groups", type=int, default=4)
    p.add_argument("--group-size", type=int, default=3)
    p.add_argument("--window", type=int, default=16, help="robustness window, frames at the take's rate [16]")
    p.add_argument("--glitch-frames", type=int, default=4, help="frames the marker is displaced [4]")
    p.add_argument("--radius", type=float, default=20.0, help="skin round the marker, mm [20]")
    p.add_argument("--quick", action="store_true", help="AnimFace only, a small model, few frames")
    p.add_argument("--work", default=None, help="keep models here (reused by later runs) [a temporary folder]")
    p.add_argument("--json", default=None)
    p.add_argument("--solver-options", default="{}",
                   help='JSON MuscleSolver / MuscleModel options of every muscle run, e.g. \'{"galea": "fixed"}\'')
    p.add_argument("--markdown", default=None)
    args = p.parse_args()
    SOLVER_OPTIONS.update(json.loads(args.solver_options))
    if args.quick:
        args.tets, args.frames, args.groups, args.group_size, args.window = 2000, 12, 2, 2, 10
        names = ["animface"]
    elif args.cases:
        names = args.cases.split(",")
    else:
        names = {"tuned": ["animface", *TUNED], "held-out": list(HELD_OUT), "all": ["animface", *TUNED, *HELD_OUT]}[args.set]
    work = Path(args.work) if args.work else Path(tempfile.mkdtemp(prefix="bench-muscles-"))
    work.mkdir(parents=True, exist_ok=True)
    results = []
    for name in names:
        t = time.perf_counter()
        take = load_take(name, work, args.tets, args.generated_frames)
        frames = take.frames(args.stride, args.frames)
        rate = take.rate / args.stride
        candidates = np.flatnonzero(take.on_model)
        groups = _spread_groups(take.corr.points(take.scan.vertices), candidates, args.groups, args.group_size)
        result = {"name": name, "held_out": take.held_out, "frames": frames.tolist(), "rate_hz": rate,
                  "markers": len(take.prepared.labels), "markers_on_model": int(candidates.size),
                  "full": dense_and_residual(take, frames, rate),
                  "leave_markers_out": leave_markers_out(take, frames, rate, groups),
                  "robustness": robustness(take, args.window, args.glitch_frames, args.radius, seed=len(name))}
        result["seconds"] = time.perf_counter() - t
        results.append(result)
        print(markdown([result], args).splitlines()[-1], flush=True)
    text = markdown(results, args)
    print(text)
    if args.markdown:
        Path(args.markdown).write_text(text)
    if args.json:
        Path(args.json).write_text(json.dumps({"machine": machine(), "args": vars(args), "results": results}, indent=1))
    if not args.work:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
