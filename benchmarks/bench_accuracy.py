"""Accuracy of the large-scale pipeline (Bickel et al. 2007, sec. 4) against dense ground truth.

The bar measured: on generated cases with dense ground truth like the bundled
one (90 markers, 0.2 mm noise, about 2 % of samples missing, a few degrees of
head rotation, real expression range), the mean dense error over the face is at
most 0.8 mm, and never worse than deforming the scan with the warp alone.

Run (about 10-15 minutes on 2 cores)::

    python benchmarks/bench_accuracy.py                       # everything, tables on stdout
    python benchmarks/bench_accuracy.py --markdown benchmarks/RESULTS_accuracy.md --save acc.json
    python benchmarks/bench_accuracy.py --quick               # 1 seed x 120 frames, a smoke run

Protocol
--------
1. Generated takes (:func:`facecap.synth.generate_performance.generate_performance`,
   ``--frames`` frames at 60 Hz, seeds ``0..--seeds-1``; the harder variants
   use ``--variant-seeds`` seeds). Each case is written to disk as a user holds
   it (:func:`~facecap.synth.write_synthetic_case.write_synthetic_case`: scan
   OBJ, C3D take, JSON map, truth npz), read back with the package's readers,
   and run through :func:`facecap.pipelines.animate_scan.animate_scan`
   (``stabilize=True``, defaults otherwise); the output folder is compared with
   the truth by :func:`facecap.report.evaluate_result.evaluate_result`.
   *Warp alone*: the same conditioned markers
   (:func:`~facecap.markers.prepare_take.prepare_markers`) mapped to face space by
   the same :class:`~facecap.deform.triharmonic_warp.TriharmonicWarp`; their
   displacements drive :func:`~facecap.deform.rbf_deform.rbf_deformation_basis`
   centred at the markers' scan points. (The shell output at the marker
   vertices is checked to equal those displacements, so both methods see
   identical data.) The same pair is run with ``stabilize=False`` and compared
   with the truth moved by the head motion relative to the rest frame, which is
   what ``evaluate_result`` does for an unstabilised result.
2. Stiffness sweep: on the first ``--sweep-seeds`` default cases, the conditioned
   face-space displacements drive :class:`~facecap.deform.thin_shell.ThinShellSolver`
   for each ``(ks, kb)``; the default's result is checked to equal
   ``animate_scan``'s output.
3. The real take (bundled ``eyebrows.c3d`` + ``ict_generic_map.json`` on the
   bundled ICT face) has no dense truth. Leave-one-marker-out: the take is
   conditioned once with all markers (``prepare_markers``, stabilised); then for
   each marker ``i`` its scan mapping is held out: the warp is refitted on the
   other markers only, those drive a shell (and a warp-alone basis) built
   without ``i``, and the displacement predicted at ``i``'s scan point is
   compared, frame by frame, with ``i``'s observed motion carried into face
   space by that same held-out warp, ``c_{-i}(p_i(t)) - c_{-i}(p_i(rest))``.
   Neither side uses ``i``'s mapping, and both pass through one warp, so the
   difference is the interpolation error of the method at a place it was not
   told about. (Also reported: the reference ``c(p_i(t)) - f_i`` of the warp
   fitted with all markers; the two differ by the warp's own change.) The same
   protocol on a generated case with truth checks that it ranks methods as the
   dense error does. Temporal smoothness: mean over vertices and frames of
   ``|x(t+1) - 2 x(t) + x(t-1)|`` (mm per frame^2 at the take's rate);
   flipped triangles: triangles whose normal turns by more than 90 degrees from
   the rest frame's, worst frame.

One process, sequential; figures across seeds are medians, with the worst seed
beside them for the bar. CPU times vary with load; this file measures accuracy.
"""

from __future__ import annotations

import argparse
import json
import platform
import shutil
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from facecap.markers.prepare_take import prepare_markers
from facecap.pipelines.animate_scan import animate_scan
from facecap.deform.rbf_deform import rbf_deformation_basis
from facecap.deform.thin_shell import DEFAULT_KB_MM2, DEFAULT_KS, ThinShellSolver
from facecap.deform.triharmonic_warp import TriharmonicWarp
from facecap.errors import FacecapWarning
from facecap.io.read_correspondence import read_correspondence
from facecap.io.read_markers import read_markers
from facecap.io.read_mesh import read_mesh
from facecap.markers.bilateral_filter import bilateral_filter
from facecap.markers.fill_gaps import fill_gaps
from facecap.report.evaluate_performance import DenseError, evaluate_performance
from facecap.report.evaluate_result import evaluate_result, read_truth
from facecap.synth.expression_curves import smooth_expression_curves
from facecap.synth.generate_performance import generate_performance
from facecap.io.ict_sample import IctSample, bundled_path, load_ict_sample
from facecap.synth.write_synthetic_case import write_synthetic_case

RATE_HZ = 60.0
BAR_MEAN_MM = 0.8

# name -> (description, builder of generate_performance keyword arguments from (seed, n_frames, sample))
VARIANTS: dict[str, str] = {
    "default": "90 markers, 0.2 mm noise, 2% gaps, 4 deg / 5 mm head motion, head band",
    "identity": "actor != generic face: identity coefficients ~ N(0, 0.5) on the 8 bundled shapes",
    "markers60": "60 markers",
    "markers120": "120 markers",
    "noise0.5": "0.5 mm marker noise",
    "gaps5": "5% of samples missing",
    "rot8": "8 deg head rotation",
    "strong": "stronger, faster expressions: intensity (0.9, 1.0), 1.2 expressions/s",
}

SWEEP: list[tuple[str, float, float]] = [
    ("ks only (kb/ks = 0)", 1.0, 0.0),
    ("kb/ks = 10 mm^2", 1.0, 10.0),
    ("kb/ks = 100 mm^2 (default)", 1.0, 100.0),
    ("kb/ks = 400 mm^2", 1.0, 400.0),
    ("kb/ks = 1000 mm^2", 1.0, 1000.0),
    ("pure bending (ks = 0)", 0.0, 100.0),
]


def variant_kwargs(name: str, seed: int, n_frames: int, sample: IctSample) -> dict[str, Any]:
    """Keyword arguments of ``generate_performance`` for a variant (seeded, deterministic)."""
    if name == "default":
        return {}
    if name == "identity":
        rng = np.random.default_rng(10_000 + seed)
        return {"identity": rng.normal(0.0, 0.5, size=sample.identity_deltas.shape[0])}
    if name == "markers60":
        return {"n_markers": 60}
    if name == "markers120":
        return {"n_markers": 120}
    if name == "noise0.5":
        return {"noise_mm": 0.5}
    if name == "gaps5":
        return {"gap_fraction": 0.05}
    if name == "rot8":
        return {"head_rotation_deg": 8.0}
    if name == "strong":
        curves = smooth_expression_curves(n_frames, sample.expression_names, rate=RATE_HZ, seed=seed,
                                          intensity=(0.9, 1.0), expressions_per_second=1.2)
        return {"curves": curves}
    raise ValueError(f"unknown variant {name!r}")


# --------------------------------------------------------------------------- helpers


def quiet(fn, *args, **kwargs):
    """Call ``fn`` with FacecapWarnings silenced (head-band markers not in the map are expected)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FacecapWarning)
        return fn(*args, **kwargs)


def face_space_displacements(prepared) -> np.ndarray:
    """What ``animate_scan`` feeds the shell: the warp of the conditioned markers minus their scan points."""
    warp = TriharmonicWarp(prepared.positions[0], prepared.scan_points)
    return warp(prepared.positions) - prepared.scan_points[None]


def deform(basis: np.ndarray, rest: np.ndarray, displacements: np.ndarray) -> np.ndarray:
    """``rest + basis^T d`` for every frame: (T, n, 3) float32."""
    return rest.astype(np.float32)[None] + np.einsum("kn,tkc->tnc", basis, displacements.astype(np.float32))


def second_difference(X: np.ndarray, labels: np.ndarray | None = None, names: list[str] | None = None):
    """Mean over frames and points of ``|x(t+1) - 2 x(t) + x(t-1)|`` (mm per frame^2).

    With region ``labels`` (and their ``names``), returns ``(overall, {region: mean})``.
    """
    per_point = np.zeros(X.shape[1])
    for t0 in range(1, X.shape[0] - 1, 128):
        t1 = min(X.shape[0] - 1, t0 + 128)
        d2 = (np.asarray(X[t0 + 1 : t1 + 1], np.float64) - 2 * np.asarray(X[t0:t1], np.float64)
              + np.asarray(X[t0 - 1 : t1 - 1], np.float64))
        per_point += np.linalg.norm(d2, axis=-1).sum(axis=0)
    per_point /= X.shape[0] - 2
    if labels is None:
        return float(per_point.mean())
    return float(per_point.mean()), {n: float(per_point[labels == k].mean()) for k, n in enumerate(names)}


def flipped_triangles(X: np.ndarray, rest: np.ndarray, F: np.ndarray) -> tuple[int, int]:
    """(most flipped triangles in one frame, frames with any flip) against the rest normals."""
    def normals(P: np.ndarray) -> np.ndarray:
        return np.cross(P[..., F[:, 1], :] - P[..., F[:, 0], :], P[..., F[:, 2], :] - P[..., F[:, 0], :])

    n0 = normals(np.asarray(rest, np.float64))
    worst, frames = 0, 0
    for t0 in range(0, X.shape[0], 64):
        nt = normals(np.asarray(X[t0 : t0 + 64], np.float64))
        flips = (np.einsum("tfc,fc->tf", nt, n0) < 0).sum(axis=1)
        worst = max(worst, int(flips.max()))
        frames += int((flips > 0).sum())
    return worst, frames


def summary(err: DenseError) -> dict[str, Any]:
    """The figures this benchmark keeps from a DenseError."""
    return {
        "mean_mm": err.mean_mm, "p95_mm": err.p95_mm, "max_mm": err.max_mm,
        "mean_pct": err.mean_pct, "p95_pct": err.p95_pct, "max_pct": err.max_pct,
        "diagonal_mm": err.diagonal_mm,
        "regions": {k: r.to_dict() for k, r in err.regions.items()},
    }


def relative_head_motion(truth_mm: np.ndarray, head_pose: np.ndarray, rest: int = 0) -> np.ndarray:
    """The truth moved by the head motion relative to the rest frame (what an unstabilised run maps)."""
    rel = np.linalg.inv(head_pose[rest])[None] @ head_pose
    return (np.einsum("tij,tnj->tni", rel[:, :3, :3].astype(np.float32), truth_mm)
            + rel[:, None, :3, 3].astype(np.float32))


# --------------------------------------------------------------------------- 1. generated cases


def run_case(variant: str, seed: int, n_frames: int, sample: IctSample, work: Path, *,
             sweep: bool = False, loo: bool = False, ablations: bool = False) -> dict[str, Any]:
    """One generated take through the pipeline and the warp-alone baseline, with and without stabilisation."""
    t_start = time.perf_counter()
    case = generate_performance(n_frames=n_frames, rate=RATE_HZ, seed=seed, sample=sample,
                                **variant_kwargs(variant, seed, n_frames, sample))
    folder = work / f"{variant}-{seed}"
    files = write_synthetic_case(case, folder / "inputs", region_labels=sample.region_labels,
                                 region_names=list(sample.region_names))
    scan = read_mesh(files.scan, unit="mm")
    take = read_markers(files.markers)
    corr = read_correspondence(files.map, scan)
    truth = read_truth(files.truth)
    truth_v = truth["vertices"]  # mm: written in mm
    regions = {"region_labels": sample.region_labels, "region_names": list(sample.region_names)}
    out: dict[str, Any] = {"variant": variant, "seed": seed}

    for stab in (True, False):
        key = "stab" if stab else "nostab"
        result = quiet(animate_scan, scan, take, corr, folder / f"animation-{key}", stabilize=stab, progress=False)
        shell_err = evaluate_result(files.truth, result.out_dir)
        shell_v = np.load(result.out_dir / "vertices.npy", mmap_mode="r")
        prepared = quiet(prepare_markers, take, scan, corr, stabilize=stab)
        disp = face_space_displacements(prepared)
        # both methods must see the same marker data: the shell interpolates it at the marker vertices
        cv = prepared.constrained_vertices
        at_markers = np.asarray(shell_v[:, cv], np.float64) - scan.vertices[cv]
        basis = rbf_deformation_basis(scan.vertices, prepared.scan_points)
        warp_v = deform(basis, scan.vertices, disp)
        target = truth_v if stab else relative_head_motion(truth_v, truth["head_pose"])
        warp_err = evaluate_performance(warp_v, target, **regions)
        out[key] = {
            "shell": summary(shell_err), "warp": summary(warp_err),
            "marker_data_mismatch_mm": float(np.abs(at_markers - disp).max()),
            "n_markers": len(prepared.labels),
            "filled_samples": int(prepared.filled.sum()),
            "stable_markers": list(prepared.stable_labels),
        }
        if stab:
            out["stab"]["smoothness"] = {
                "shell": second_difference(shell_v), "warp": second_difference(warp_v),
                "truth": second_difference(truth_v),
            }
            out["stab"]["stabilization_residual_median_mm"] = float(np.nanmedian(prepared.stabilization_residual))
            # error of the conditioned face-space marker displacements against the true skin displacement
            skin = np.asarray(truth_v[:, cv], np.float64) - scan.vertices[cv]
            out["stab"]["marker_displacement_error_mm"] = float(np.linalg.norm(disp - skin, axis=2).mean())
            if sweep or ablations:
                shell = quiet(ThinShellSolver, scan.vertices, scan.faces, cv)
                if float(np.abs(deform(shell.basis, scan.vertices, disp[-1:]) - shell_v[-1:]).max()) > 1e-3:
                    raise RuntimeError("ThinShellSolver at the defaults does not reproduce animate_scan's output")
            if sweep:
                out["sweep"] = stiffness_sweep(scan, cv, {"pipeline": disp, "exact markers": skin},
                                               truth_v, shell_v, regions)
            if ablations:
                out["ablations"] = error_budget(case, take, corr, prepared, shell.basis, basis, skin, truth_v)
            if loo:
                out["loo"] = leave_one_out(scan, prepared, truth_v=truth_v, every=6)
        del shell_v, warp_v, target
    shutil.rmtree(folder, ignore_errors=True)
    out["seconds"] = time.perf_counter() - t_start
    return out


def error_budget(case, take, corr, prepared, shell_basis, warp_basis, skin, truth_v) -> dict[str, Any]:
    """Mean dense error when parts of the conditioning are replaced by what the generator knows.

    ``exact markers``: the shell / warp driven by the true skin displacement at
    the marker vertices (no noise, no gaps, no head motion, no marker offset):
    the interpolation error alone. ``true head pose``: gap filling and the
    bilateral filter as in the pipeline, but the head motion removed with the
    generator's pose instead of the pipeline's stabilisation. ``sigma_t 0.05 s``:
    the bilateral filter with a 0.05 s temporal sigma instead of its default
    0.02 s, after the true or the pipeline's stabilising transforms.
    """
    scan = case.scan
    columns = [take.labels.index(s) for s in prepared.labels]
    world = case.mocap_from_scan[None] @ case.head_pose
    to_rest = world[0][None] @ np.linalg.inv(world)  # mocap frame t -> mocap frame at the rest pose
    filled = fill_gaps(take.positions, rate=take.rate).positions
    oracle = np.einsum("tij,tkj->tki", to_rest[:, :3, :3], filled) + to_rest[:, None, :3, 3]
    # the pipeline's own stabilising transforms (what condition_take applies before filtering)
    stabilised = (np.einsum("tij,tkj->tki", prepared.head_rotations, filled)
                  + prepared.head_translations[:, None])

    def displacements(P: np.ndarray) -> np.ndarray:
        P = P[:, columns]
        return TriharmonicWarp(P[0], prepared.scan_points)(P) - prepared.scan_points[None]

    drives = {
        "exact markers": skin,
        "true head pose": displacements(bilateral_filter(oracle, rate=take.rate)),
        "true head pose, sigma_t 0.05 s": displacements(bilateral_filter(oracle, rate=take.rate, temporal_sigma_s=0.05)),
        "pipeline stabilisation, sigma_t 0.05 s": displacements(
            bilateral_filter(stabilised, rate=take.rate, temporal_sigma_s=0.05)),
    }
    rows = {}
    for name, d in drives.items():
        rows[name] = {
            "shell_mean_mm": evaluate_performance(deform(shell_basis, scan.vertices, d), truth_v).mean_mm,
            "warp_mean_mm": evaluate_performance(deform(warp_basis, scan.vertices, d), truth_v).mean_mm,
            "marker_displacement_error_mm": float(np.linalg.norm(d - skin, axis=2).mean()),
        }
    return rows


def stiffness_sweep(scan, constrained, drives: dict[str, np.ndarray], truth_v, shell_v, regions) -> dict[str, Any]:
    """Dense error for each (ks, kb) of SWEEP, for each set of marker displacements in ``drives``."""
    rows = {}
    for label, ks, kb in SWEEP:
        solver = quiet(ThinShellSolver, scan.vertices, scan.faces, constrained, ks=ks, kb=kb)
        rows[label] = {"ks": ks, "kb": kb}
        for name, disp in drives.items():
            V = deform(solver.basis, scan.vertices, disp)
            rows[label][name] = summary(evaluate_performance(V, truth_v, **regions))
            if name == "pipeline" and ks == DEFAULT_KS and kb == DEFAULT_KB_MM2:
                rows[label]["max_diff_vs_animate_scan_mm"] = float(np.abs(V - shell_v).max())
    return rows


# --------------------------------------------------------------------------- 3. leave one marker out


def leave_one_out(scan, prepared, *, truth_v: np.ndarray | None = None, every: int = 1) -> dict[str, Any]:
    """Leave-one-marker-out prediction error of the thin shell and the warp alone (see module docstring).

    With ``truth_v`` (a generated case), the true displacement of the held-out
    marker's vertex is also scored, to check the protocol against the truth.
    """
    P = prepared.positions  # (T, K, 3) conditioned, mocap space
    S = prepared.scan_points
    cv = prepared.constrained_vertices
    K = S.shape[0]
    full_warp = TriharmonicWarp(P[0], S)
    ref_all = full_warp(P) - S[None]  # (T, K, 3)
    held = list(range(0, K, every))
    per = {"shell": [], "warp": [], "shell_vs_full_warp": [], "warp_vs_full_warp": [],
           "shell_vs_truth": [], "warp_vs_truth": [], "reference_vs_truth": []}
    per_marker = []
    for i in held:
        others = np.delete(np.arange(K), i)
        warp_i = TriharmonicWarp(P[0, others], S[others])
        disp_o = warp_i(P[:, others]) - S[None, others]
        ref = warp_i(P[:, i]) - warp_i(P[0, i])  # (T, 3): i's observed motion through the held-out warp
        shell = quiet(ThinShellSolver, scan.vertices, scan.faces, cv[others])
        w_shell = shell.basis[:, cv[i]].astype(np.float64)  # (K-1,) the shell's weights at i's vertex
        # rbf_deformation_basis wants a mesh-sized point set (>= 3 points): take the column at i's vertex
        w_warp = rbf_deformation_basis(scan.vertices, S[others])[:, cv[i]].astype(np.float64)
        pred_shell = np.einsum("k,tkc->tc", w_shell, disp_o)
        pred_warp = np.einsum("k,tkc->tc", w_warp, disp_o)
        e = {
            "shell": np.linalg.norm(pred_shell - ref, axis=1),
            "warp": np.linalg.norm(pred_warp - ref, axis=1),
            "shell_vs_full_warp": np.linalg.norm(pred_shell - ref_all[:, i], axis=1),
            "warp_vs_full_warp": np.linalg.norm(pred_warp - ref_all[:, i], axis=1),
        }
        if truth_v is not None:
            true_d = np.asarray(truth_v[:, cv[i]], np.float64) - scan.vertices[cv[i]]
            e["shell_vs_truth"] = np.linalg.norm(pred_shell - true_d, axis=1)
            e["warp_vs_truth"] = np.linalg.norm(pred_warp - true_d, axis=1)
            e["reference_vs_truth"] = np.linalg.norm(ref - true_d, axis=1)
        for k, v in e.items():
            per[k].append(v)
        per_marker.append({"label": prepared.labels[i], "shell_mean_mm": float(e["shell"].mean()),
                           "warp_mean_mm": float(e["warp"].mean()),
                           "motion_rms_mm": float(np.sqrt((ref ** 2).sum(axis=1).mean()))})
    stats = {}
    for k, v in per.items():
        if v:
            a = np.concatenate(v)
            stats[k] = {"mean_mm": float(a.mean()), "p95_mm": float(np.percentile(a, 95)), "max_mm": float(a.max())}
    wins = sum(m["shell_mean_mm"] <= m["warp_mean_mm"] for m in per_marker)
    return {"held_out": len(held), "stats": stats, "shell_better_markers": wins, "per_marker": per_marker}


def run_real_take(sample: IctSample, work: Path) -> dict[str, Any]:
    """The bundled AnimFace take on the bundled ICT face: LOO, smoothness, flips."""
    t_start = time.perf_counter()
    scan = sample.mesh
    take = read_markers(bundled_path("eyebrows.c3d"))
    corr = read_correspondence(bundled_path("ict_generic_map.json"), scan)
    result = quiet(animate_scan, scan, take, corr, work / "animface", stabilize=True, progress=False)
    shell_v = np.load(result.out_dir / "vertices.npy", mmap_mode="r")
    prepared = quiet(prepare_markers, take, scan, corr, stabilize=True)
    disp = face_space_displacements(prepared)
    basis = rbf_deformation_basis(scan.vertices, prepared.scan_points)
    warp_v = deform(basis, scan.vertices, disp)
    flips_shell = flipped_triangles(shell_v, scan.vertices, scan.faces)
    flips_warp = flipped_triangles(warp_v, scan.vertices, scan.faces)
    face_markers = disp + prepared.scan_points[None]
    out = {
        "frames": take.n_frames, "markers": len(prepared.labels), "rate_hz": take.rate,
        "stable_markers": list(prepared.stable_labels),
        "stabilization_residual_median_mm": float(np.nanmedian(prepared.stabilization_residual)),
        "max_vertex_motion_mm": float(np.linalg.norm(np.asarray(shell_v) - scan.vertices[None], axis=2).max()),
        "smoothness": {"shell": second_difference(shell_v), "warp": second_difference(warp_v),
                       "markers_face_space": second_difference(face_markers)},
        "smoothness_regions": {
            "shell": second_difference(shell_v, sample.region_labels, list(sample.region_names))[1],
            "warp": second_difference(warp_v, sample.region_labels, list(sample.region_names))[1]},
        "flipped": {"shell": {"worst_frame": flips_shell[0], "frames": flips_shell[1]},
                    "warp": {"worst_frame": flips_warp[0], "frames": flips_warp[1]}},
        "n_triangles": int(scan.faces.shape[0]),
        "marker_data_mismatch_mm": float(np.abs(np.asarray(shell_v[:, prepared.constrained_vertices], np.float64)
                                                - scan.vertices[prepared.constrained_vertices] - disp).max()),
    }
    del shell_v, warp_v
    out["loo"] = leave_one_out(scan, prepared)
    shutil.rmtree(work / "animface", ignore_errors=True)
    out["seconds"] = time.perf_counter() - t_start
    return out


# --------------------------------------------------------------------------- reporting


def med(values: list[float]) -> float:
    return float(statistics.median(values))


def fmt(x: float, nd: int = 2) -> str:
    return f"{x:.{nd}f}"


def tables(results: dict[str, Any]) -> str:
    """All results as markdown."""
    lines: list[str] = []
    cases = results["cases"]
    by_variant: dict[str, list[dict]] = {}
    for c in cases:
        by_variant.setdefault(c["variant"], []).append(c)

    lines += ["### Dense error against ground truth (stabilised, `animate_scan(stabilize=True)`)", "",
              "Median over seeds of each run's mean / p95 / max over all vertices and frames; "
              "worst seed's mean in brackets. % = of the face's bounding-box diagonal.", "",
              "| case | seeds | markers | shell mean mm (worst) | shell p95 | shell max | shell mean % | "
              "warp mean mm (worst) | warp p95 | warp max | shell < warp (mean) in | bar mean <= 0.8 |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, cs in by_variant.items():
        s = [c["stab"]["shell"] for c in cs]
        w = [c["stab"]["warp"] for c in cs]
        wins = sum(a["mean_mm"] <= b["mean_mm"] for a, b in zip(s, w))
        ok = all(a["mean_mm"] <= BAR_MEAN_MM for a in s) and wins == len(cs)
        lines.append(
            f"| {name} | {len(cs)} | {cs[0]['stab']['n_markers']} | {fmt(med([x['mean_mm'] for x in s]), 3)} "
            f"({fmt(max(x['mean_mm'] for x in s), 3)}) | {fmt(med([x['p95_mm'] for x in s]))} | "
            f"{fmt(med([x['max_mm'] for x in s]))} | {fmt(med([x['mean_pct'] for x in s]), 3)} | "
            f"{fmt(med([x['mean_mm'] for x in w]), 3)} ({fmt(max(x['mean_mm'] for x in w), 3)}) | "
            f"{fmt(med([x['p95_mm'] for x in w]))} | {fmt(med([x['max_mm'] for x in w]))} | "
            f"{wins}/{len(cs)} | {'yes' if ok else '**no**'} |")
    lines.append("")
    diag = med([c["stab"]["shell"]["diagonal_mm"] for c in cases])
    lines.append(f"Bounding-box diagonal of the face: {diag:.1f} mm (median over cases).")
    lines.append("")

    lines += ["### Without head stabilisation (`stabilize=False`), against the truth with head motion", "",
              "| case | shell mean mm (worst) | shell p95 | shell max | warp mean mm (worst) | warp p95 | "
              "warp max | shell < warp in |",
              "|---|---|---|---|---|---|---|---|"]
    for name, cs in by_variant.items():
        s = [c["nostab"]["shell"] for c in cs]
        w = [c["nostab"]["warp"] for c in cs]
        wins = sum(a["mean_mm"] <= b["mean_mm"] for a, b in zip(s, w))
        lines.append(
            f"| {name} | {fmt(med([x['mean_mm'] for x in s]), 3)} ({fmt(max(x['mean_mm'] for x in s), 3)}) | "
            f"{fmt(med([x['p95_mm'] for x in s]))} | {fmt(med([x['max_mm'] for x in s]))} | "
            f"{fmt(med([x['mean_mm'] for x in w]), 3)} ({fmt(max(x['mean_mm'] for x in w), 3)}) | "
            f"{fmt(med([x['p95_mm'] for x in w]))} | {fmt(med([x['max_mm'] for x in w]))} | {wins}/{len(cs)} |")
    lines.append("")

    region_names = list(cases[0]["stab"]["shell"]["regions"])
    for stat in ("mean_mm", "p95_mm"):
        lines += [f"### Per region, stabilised: {stat.replace('_mm', '')} error, shell / warp alone (mm, median over seeds)", "",
                  "| case | " + " | ".join(region_names) + " |", "|---|" + "---|" * len(region_names)]
        for name, cs in by_variant.items():
            cells = []
            for r in region_names:
                a = med([c["stab"]["shell"]["regions"][r][stat] for c in cs])
                b = med([c["stab"]["warp"]["regions"][r][stat] for c in cs])
                cells.append(f"{a:.2f} / {b:.2f}" if a <= b else f"**{a:.2f}** / {b:.2f}")
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        lines += ["", "Bold: the shell is worse than the warp alone in that region.", ""]

    smooth = [c["stab"]["smoothness"] for c in by_variant.get("default", [])]
    if smooth:
        lines += ["Temporal smoothness, default cases (mean |second difference| of vertex positions, "
                  "mm per frame^2 at 60 Hz, median over seeds): "
                  f"truth {med([s['truth'] for s in smooth]):.4f}, shell {med([s['shell'] for s in smooth]):.4f}, "
                  f"warp alone {med([s['warp'] for s in smooth]):.4f}.", ""]

    sweeps = [c["sweep"] for c in cases if "sweep" in c]
    if sweeps:
        lines += [f"### Stiffness sweep (default cases, {len(sweeps)} seeds; median over seeds, worst seed's mean in brackets)", "",
                  "Pipeline: the conditioned face-space marker displacements that `animate_scan` uses. "
                  "Exact markers: the true skin displacement at the marker vertices (interpolation error alone).", "",
                  "| ks, kb | pipeline mean mm (worst) | p95 | max | mouth mean | eyes mean | exact-marker mean | exact-marker p95 |",
                  "|---|---|---|---|---|---|---|---|"]
        for label in sweeps[0]:
            rs = [s[label]["pipeline"] for s in sweeps]
            xs = [s[label]["exact markers"] for s in sweeps]
            lines.append(
                f"| {label} | {fmt(med([r['mean_mm'] for r in rs]), 3)} ({fmt(max(r['mean_mm'] for r in rs), 3)}) | "
                f"{fmt(med([r['p95_mm'] for r in rs]))} | {fmt(med([r['max_mm'] for r in rs]))} | "
                f"{fmt(med([r['regions']['mouth']['mean_mm'] for r in rs]), 3)} | "
                f"{fmt(med([r['regions']['eyes']['mean_mm'] for r in rs]), 3)} | "
                f"{fmt(med([r['mean_mm'] for r in xs]), 3)} | {fmt(med([r['p95_mm'] for r in xs]))} |")
        sw = [c for c in cases if "sweep" in c]
        ws = [c["stab"]["warp"] for c in sw]
        wx = [c["ablations"]["exact markers"]["warp_mean_mm"] for c in sw if "ablations" in c]
        lines.append(f"| warp alone (reference) | {fmt(med([w['mean_mm'] for w in ws]), 3)} | "
                     f"{fmt(med([w['p95_mm'] for w in ws]))} | {fmt(med([w['max_mm'] for w in ws]))} | "
                     f"{fmt(med([w['regions']['mouth']['mean_mm'] for w in ws]), 3)} | "
                     f"{fmt(med([w['regions']['eyes']['mean_mm'] for w in ws]), 3)} | "
                     f"{fmt(med(wx), 3) if wx else '-'} | - |")
        diffs = [s[l]["max_diff_vs_animate_scan_mm"] for s in sweeps for l in s if "max_diff_vs_animate_scan_mm" in s[l]]
        lines += ["", f"(The default row equals `animate_scan`'s output to {max(diffs):.1e} mm.)", ""]

    abl = [c for c in cases if "ablations" in c]
    if abl:
        names = list(abl[0]["ablations"])
        variants = list(dict.fromkeys(c["variant"] for c in abl))
        lines += ["### Error budget: the pipeline with parts replaced by the generator's truth (stabilised, mean dense error mm, median over seeds)", "",
                  "marker err: mean distance between the face-space marker displacements that drive the shell and the "
                  "true skin displacement at those vertices.", "",
                  "| case | drive | shell mean | warp mean | marker err |", "|---|---|---|---|---|"]
        for v in variants:
            cs = [c for c in abl if c["variant"] == v]
            lines.append(f"| {v} | pipeline (as shipped) | {fmt(med([c['stab']['shell']['mean_mm'] for c in cs]), 3)} | "
                         f"{fmt(med([c['stab']['warp']['mean_mm'] for c in cs]), 3)} | "
                         f"{fmt(med([c['stab']['marker_displacement_error_mm'] for c in cs]), 3)} |")
            for n in names:
                lines.append(f"| {v} | {n} | {fmt(med([c['ablations'][n]['shell_mean_mm'] for c in cs]), 3)} | "
                             f"{fmt(med([c['ablations'][n]['warp_mean_mm'] for c in cs]), 3)} | "
                             f"{fmt(med([c['ablations'][n]['marker_displacement_error_mm'] for c in cs]), 3)} |")
        lines.append("")

    loo_syn = [c["loo"] for c in cases if "loo" in c]
    real = results.get("real_take")
    if real or loo_syn:
        lines += ["### Leave one marker out (displacement predicted at the held-out marker, mm)", "",
                  "| take | held out | shell mean | shell p95 | warp mean | warp p95 | shell better at | "
                  "shell mean vs full-warp ref | warp mean vs full-warp ref | shell vs truth | warp vs truth | ref vs truth |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        rows = [(f"generated {c['variant']} seed {c['seed']}", c["loo"]) for c in cases if "loo" in c]
        if real:
            rows.append(("AnimFace eyebrows (real)", real["loo"]))
        for name, L in rows:
            st = L["stats"]
            g = lambda k, f="mean_mm": fmt(st[k][f], 3) if k in st else "-"  # noqa: E731
            lines.append(f"| {name} | {L['held_out']} | {g('shell')} | {g('shell', 'p95_mm')} | {g('warp')} | "
                         f"{g('warp', 'p95_mm')} | {L['shell_better_markers']}/{L['held_out']} | "
                         f"{g('shell_vs_full_warp')} | {g('warp_vs_full_warp')} | {g('shell_vs_truth')} | "
                         f"{g('warp_vs_truth')} | {g('reference_vs_truth')} |")
        lines.append("")
    if real:
        f = real["flipped"]
        lines += [f"Real take: {real['frames']} frames, {real['markers']} markers, stabilised on "
                  f"{', '.join(real['stable_markers'])} (median residual {real['stabilization_residual_median_mm']:.2f} mm); "
                  f"max vertex motion {real['max_vertex_motion_mm']:.1f} mm. "
                  f"Smoothness (mean |second difference|, mm/frame^2): shell {real['smoothness']['shell']:.4f}, "
                  f"warp alone {real['smoothness']['warp']:.4f}, face-space markers {real['smoothness']['markers_face_space']:.4f}. "
                  f"Flipped triangles (of {real['n_triangles']}), worst frame / frames with any: shell "
                  f"{f['shell']['worst_frame']} / {f['shell']['frames']}, warp alone {f['warp']['worst_frame']} / "
                  f"{f['warp']['frames']}.", ""]
        sr = real["smoothness_regions"]
        lines += ["Real take, smoothness per region (mm/frame^2, shell / warp alone): "
                  + "; ".join(f"{r} {sr['shell'][r]:.4f} / {sr['warp'][r]:.4f}" for r in sr["shell"]) + ".", ""]
        worst = sorted(real["loo"]["per_marker"], key=lambda m: -m["shell_mean_mm"])[:6]
        lines += ["Real take, markers hardest to predict (mean mm, shell / warp alone; RMS motion): "
                  + "; ".join(f"{m['label']} {m['shell_mean_mm']:.2f} / {m['warp_mean_mm']:.2f} ({m['motion_rms_mm']:.2f})"
                              for m in worst) + ".", ""]
    return "\n".join(lines)


def verdict(results: dict[str, Any]) -> list[str]:
    """Does the bar hold in every case tested? One line per failure, or one line saying it holds."""
    fails = []
    for c in results["cases"]:
        s, w = c["stab"]["shell"], c["stab"]["warp"]
        if s["mean_mm"] > BAR_MEAN_MM:
            fails.append(f"{c['variant']} seed {c['seed']}: shell mean {s['mean_mm']:.3f} mm > {BAR_MEAN_MM} mm")
        if s["mean_mm"] > w["mean_mm"]:
            fails.append(f"{c['variant']} seed {c['seed']}: shell mean {s['mean_mm']:.3f} mm > warp alone {w['mean_mm']:.3f} mm")
    return fails or ["the bar holds in every generated case tested"]


def unstabilised_notes(results: dict[str, Any]) -> list[str]:
    """Where, without stabilisation, the shell loses to the warp alone (informative, not the bar)."""
    return [f"{c['variant']} seed {c['seed']}: shell {c['nostab']['shell']['mean_mm']:.3f} mm > warp alone "
            f"{c['nostab']['warp']['mean_mm']:.3f} mm" for c in results["cases"]
            if c["nostab"]["shell"]["mean_mm"] > c["nostab"]["warp"]["mean_mm"]]


def machine() -> str:
    cpu = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import os
    import scipy
    return (f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}, "
            f"scipy {scipy.__version__}, {platform.system()} {platform.release()}")


def code_version() -> str:
    """The commit the package was measured at, and whether src/ had local changes (read-only git calls)."""
    import subprocess
    root = Path(__file__).resolve().parent.parent
    try:
        head = subprocess.run(["git", "-C", str(root), "log", "-1", "--format=%h %s"], capture_output=True,
                              text=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--", "src"], capture_output=True,
                               text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    changed = [line.split(None, 1)[1] for line in dirty.splitlines() if line.strip()]
    return head + (f" (uncommitted changes in {', '.join(changed[:5])}{' ...' if len(changed) > 5 else ''})"
                   if changed else "")


# --------------------------------------------------------------------------- main


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=600)
    ap.add_argument("--seeds", type=int, default=5, help="seeds of the default case")
    ap.add_argument("--variant-seeds", type=int, default=3, help="seeds of each harder variant")
    ap.add_argument("--sweep-seeds", type=int, default=3)
    ap.add_argument("--variants", nargs="*", default=list(VARIANTS), choices=list(VARIANTS))
    ap.add_argument("--no-real", action="store_true", help="skip the real take")
    ap.add_argument("--no-loo-synthetic", action="store_true", help="skip the LOO protocol check on a generated case")
    ap.add_argument("--ablation-variants", nargs="*", default=["default", "noise0.5"],
                    help="variants whose cases also get the error budget (truth-replaced conditioning)")
    ap.add_argument("--quick", action="store_true", help="1 seed, 120 frames, every variant: a smoke run")
    ap.add_argument("--save", type=Path, help="write all figures as JSON here (also after every case)")
    ap.add_argument("--resume", action="store_true",
                    help="keep the cases (and real take) already in --save when they were measured on the same "
                         "code with the same --frames, and run only the rest")
    ap.add_argument("--markdown", type=Path, help="write the results section here")
    args = ap.parse_args(argv)
    if args.quick:
        args.frames, args.seeds, args.variant_seeds, args.sweep_seeds = 120, 1, 1, 1

    t0 = time.perf_counter()
    sample = load_ict_sample()
    work = Path(tempfile.mkdtemp(prefix="facecap-bench-accuracy-"))
    results: dict[str, Any] = {"machine": machine(), "code": code_version(),
                               "command": " ".join(["python"] + sys.argv),
                               "frames": args.frames, "rate_hz": RATE_HZ, "cases": []}
    done: dict[tuple[str, int], dict] = {}
    if args.resume and args.save and args.save.is_file():
        old = json.loads(args.save.read_text())
        if old.get("code") == results["code"] and old.get("frames") == args.frames:
            done = {(c["variant"], c["seed"]): c for c in old["cases"]}
            if "real_take" in old:
                results["real_take"] = old["real_take"]
            results["resumed_seconds"] = (old["seconds"] if "seconds" in old else
                                          old.get("partial_seconds", 0.0) + old.get("resumed_seconds", 0.0))
            print(f"resuming: {len(done)} case(s) kept from {args.save}", file=sys.stderr)
        else:
            print(f"not resuming: {args.save} was measured on other code or frames", file=sys.stderr)

    def checkpoint() -> None:
        if args.save:
            results["partial_seconds"] = time.perf_counter() - t0
            args.save.write_text(json.dumps(results, indent=1))

    try:
        for variant in args.variants:
            n_seeds = args.seeds if variant == "default" else args.variant_seeds
            for seed in range(n_seeds):
                if (variant, seed) in done:
                    results["cases"].append(done[(variant, seed)])
                    continue
                c = run_case(variant, seed, args.frames, sample, work,
                             sweep=variant == "default" and seed < args.sweep_seeds,
                             loo=variant == "default" and seed == 0 and not args.no_loo_synthetic,
                             ablations=variant in args.ablation_variants)
                results["cases"].append(c)
                print(f"{variant:>10} seed {seed}: shell {c['stab']['shell']['mean_mm']:.3f} mm, "
                      f"warp {c['stab']['warp']['mean_mm']:.3f} mm; unstabilised shell "
                      f"{c['nostab']['shell']['mean_mm']:.3f}, warp {c['nostab']['warp']['mean_mm']:.3f} "
                      f"({c['seconds']:.0f} s)", file=sys.stderr, flush=True)
                checkpoint()
        if not args.no_real and "real_take" not in results:
            results["real_take"] = run_real_take(sample, work)
            checkpoint()
            print(f"real take done ({results['real_take']['seconds']:.0f} s)", file=sys.stderr, flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    results.pop("partial_seconds", None)
    results["seconds"] = time.perf_counter() - t0 + results.pop("resumed_seconds", 0.0)
    results["verdict"] = verdict(results)

    md = tables(results)
    print(md)
    results["unstabilised_shell_worse"] = unstabilised_notes(results)
    print("Verdict: " + "; ".join(results["verdict"]))
    print("Unstabilised, shell worse than warp alone: " + ("; ".join(results["unstabilised_shell_worse"]) or "never"))
    print(f"\n{results['seconds']:.0f} s on {results['machine']}")
    if args.save:
        args.save.write_text(json.dumps(results, indent=1))
    if args.markdown:
        args.markdown.write_text(
            "## Accuracy of the large-scale pipeline\n\n"
            f"Machine: {results['machine']}. Code: {results['code']}. Command: `{results['command']}` "
            f"({results['seconds'] / 60:.1f} min). {args.frames} frames at {RATE_HZ:.0f} Hz per generated take.\n\n"
            + md + "\n\nVerdict (stabilised, the bar): " + "; ".join(results["verdict"])
            + "\n\nUnstabilised, shell worse than warp alone: "
            + ("; ".join(results["unstabilised_shell_worse"]) or "never") + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
