"""``facecap demo``'s job: the main job on the bundled sample, with pictures and a report.

The steps, in the order :func:`run_demo` runs them:

1. A performance generated on the bundled ICT face (90 markers 1.5 mm above the skin, 0.2 mm
   noise, ~2% occlusions, head motion, a different rigid frame), written as a user would hold it:
   ``inputs/scan.obj``, ``inputs/take.c3d``, ``inputs/map.json``, ``inputs/truth.npz``.
2. Exactly what ``facecap animate`` runs on those files (``animation/``, with a USD export, its
   review page against the truth), and the warp-alone baseline (:func:`_generated_take`); both
   evaluated against the dense ground truth, with frames, error maps and the residuals and
   error over time drawn (:func:`_draw_generated_take`, ``pictures/``).
3. The scan workflow of Huang et al. 2011 on the same take (``scans/``, :func:`_scan_workflow`).
4. The same face animated from the real AnimFace take (``animface/``, :func:`_animate_real_take`),
   and a stretch of it solved for muscle activations on an anatomical model of the face
   (``muscles/``, :func:`_muscle_run`).
5. The wrinkle layer on generated footage of painted wrinkles (``wrinkles/``, :func:`_wrinkle_layer`).
6. ``demo_summary.json``: each step's figures, and the lines :func:`run_demo` returns.

Everything is written into a staging folder renamed into place at the end. A second run into
the same folder is refused (one line, before any work) unless ``overwrite`` (``--overwrite``) is
given: pictures, exports or notes added to an earlier demo folder are never deleted unasked.
Every path the demo's files record is where the file lies once the folder is in place.
"""

from __future__ import annotations

import json
import time
import warnings
from pathlib import Path
from typing import Any, NamedTuple

import igl
import numpy as np
from scipy.spatial.transform import Rotation

from ..anatomy import build_anatomy, render_anatomy_layout
from ..cameras import Camera, RayCaster, read_camera_file, read_image
from ..deform.rbf_deform import rbf_deformation_basis
from ..errors import FacecapWarning, InputError
from ..io.atomic_write import atomic_folder, atomic_path, recorded_path
from ..io.mocap_correspondence import read_mocap_correspondence
from ..io.read_correspondence import read_correspondence
from ..io.read_markers import read_markers
from ..io.read_mesh import read_mesh
from ..io.read_result import read_result
from ..muscles import FRAME_FLAG_MEANINGS
from ..report import MeshPanel, evaluate_performance, plot_series, render_mesh, render_side_by_side
from ..report.evaluate_result import evaluate_result, read_truth
from ..structures import MarkerSequence, Mesh
from ..synth import write_planned_scans
from ..synth.generate_performance import generate_performance
from ..io.ict_sample import bundled_path, load_ict_sample
from ..synth.wrinkles import every_wrinkle_at_once
from ..synth.write_footage_case import write_footage_case
from ..synth.write_synthetic_case import write_synthetic_case
from ..wrinkles import fit_cross_sections, large_scale_in_mocap, wedge_intensity
from ..wrinkles.fit_cross_sections import DEFAULT_ROUNDING
from .animate_scan import AnimationResult, animate_scan
from .blend_take import blend_take
from .capture_wrinkles import capture_wrinkles
from .plan_scans import plan_scans
from .register_planned_scans import register_planned_scans
from .solve_muscle_take import solve_muscle_take
from .view_result import view_result
from .write_muscle_result import plot_muscle_activations

__all__ = ["run_demo"]

_DEMO_MARKER = "demo_summary.json"


def run_demo(out_dir: str | Path = "facecap-demo", *, n_frames: int = 300, progress: bool = True,
             overwrite: bool = False) -> list[str]:
    """Run the demo and return printable summary lines.

    Parameters
    ----------
    out_dir : str or Path, default 'facecap-demo'
        Output folder. An earlier demo there is replaced only with ``overwrite``
        (else refused before any work); any other non-empty folder is refused.
    n_frames : int, default 300
        Frames of the generated take (60 Hz).
    progress : bool, default True
        Progress bars.
    overwrite : bool, default False
        Replace an earlier demo in ``out_dir``.

    Returns
    -------
    list of str
    """
    if n_frames < 10:
        raise InputError(f"--frames: expected at least 10, got {n_frames}")
    out = Path(out_dir)
    t_start = time.perf_counter()
    with atomic_folder(out, marker_file=_DEMO_MARKER, overwrite=overwrite) as stage:
        (stage / "pictures").mkdir()
        sample = load_ict_sample()
        case = generate_performance(n_frames=n_frames, seed=7, sample=sample)
        files = write_synthetic_case(
            case, stage / "inputs", region_labels=sample.region_labels, region_names=list(sample.region_names)
        )
        generated = _generated_take(stage, sample, files, progress)
        error_vmax, picture_ranges = _draw_generated_take(stage / "pictures", generated)
        steps = {"generated_take": _said_of_generated_take(generated)}
        steps["scan_workflow"] = _scan_workflow(stage, case, files, generated.shell_error, generated.vertices,
                                                error_vmax, progress)
        picture_ranges.update(steps["scan_workflow"].pop("picture_ranges"))
        steps["animface_take"] = _animate_real_take(stage, sample, progress)
        steps["muscles"] = _muscle_run(stage, sample, steps["animface_take"]["summary"]["busiest_frame"], progress)
        steps["wrinkles"] = _wrinkle_layer(stage, progress)
        summary = {name: step["summary"] for name, step in steps.items()}
        summary["seconds"] = time.perf_counter() - t_start
        summary["picture_colour_ranges_mm"] = picture_ranges
        (stage / _DEMO_MARKER).write_text(json.dumps(summary, indent=1))
        lines = [line for step in steps.values() for line in step["lines"]]
    lines.append(f"wrote {out}/ in {time.perf_counter() - t_start:.1f} s: animation/ (vertices.npy, rig/, "
                 f"performance_rig.usdc, performance.glb, report.html), scans/ (plan, scans, bases, blend), animface/, "
                 f"muscles/ (model, solved take), "
                 f"wrinkles/ (footage, large scale, with wrinkles, wrinkles.json), "
                 f"pictures/, {_DEMO_MARKER}")
    lines.append(f"look at it: facecap view {out}/animation --truth {out}/inputs/truth.npz "
                 "(the take in the browser, with its error against the truth)")
    return lines


class _GeneratedTake(NamedTuple):
    """The generated take animated as ``facecap animate`` does, and by the warp alone, against its truth."""

    scan: Mesh
    take: MarkerSequence
    result: AnimationResult
    vertices: Any  # (T, n, 3) float32, the thin shell's vertices.npy (memory-mapped)
    truth_vertices: np.ndarray  # (T, n, 3)
    warp_alone: np.ndarray  # (T, n, 3) float32
    shell_error: Any  # DenseError
    warp_error: Any  # DenseError


def _generated_take(stage: Path, sample, files, progress: bool) -> _GeneratedTake:
    """The main job, exactly as ``facecap animate`` runs it from the files, its review, and the warp alone."""
    scan = read_mesh(files.scan, unit="mm")
    take = read_markers(files.markers)
    corr = read_correspondence(files.map, scan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FacecapWarning)  # head-band markers not in the map: expected
        result = animate_scan(
            scan, take, corr, stage / "animation", stabilize=True, exports=("usd",), progress=progress,
            extra_metadata={"map": recorded_path(files.map, folder=stage / "animation")},
        )
    shell_error = evaluate_result(files.truth, result.out_dir)
    view_result(result.out_dir, truth=files.truth)  # the glTF, review.html with the error heat map, report.html
    vertices = np.load(result.out_dir / "vertices.npy", mmap_mode="r")
    truth_v = read_truth(files.truth)["vertices"]
    warp_only = _warp_alone(scan, corr, result, vertices)
    warp_error = evaluate_performance(
        warp_only, truth_v, region_labels=sample.region_labels, region_names=list(sample.region_names)
    )
    return _GeneratedTake(scan, take, result, vertices, truth_v, warp_only, shell_error, warp_error)


def _warp_alone(scan: Mesh, corr, result: AnimationResult, vertices) -> np.ndarray:
    """The baseline: the scan deformed by the RBF warp alone, from the thin shell's motion at the markers."""
    const = corr.vertex_indices[:, 0]
    labels = json.loads((result.out_dir / "performance.json").read_text())["markers"]
    rows = [corr.labels.index(s) for s in labels]
    marker_vertices = const[rows]
    shell_disp_at_markers = vertices[:, marker_vertices] - scan.vertices[marker_vertices].astype(np.float32)
    basis = rbf_deformation_basis(scan.vertices, scan.vertices[marker_vertices])
    return scan.vertices.astype(np.float32)[None] + np.einsum("kn,tkc->tnc", basis, shell_disp_at_markers)


def _draw_generated_take(pictures: Path, generated: _GeneratedTake) -> tuple[float, dict[str, list[float]]]:
    """The generated take's pictures; returns the dense-error maps' colour top (mm) and the ranges drawn."""
    scan, vertices, truth_v, warp_only = generated.scan, generated.vertices, generated.truth_vertices, generated.warp_alone
    shell_error = generated.shell_error
    n_frames = truth_v.shape[0]
    F = scan.faces
    worst = int(np.argmax(shell_error.per_frame_mean_mm))
    busy = int(np.argmax(np.abs(truth_v - truth_v[0]).reshape(n_frames, -1).mean(axis=1)))
    shell_err_v = np.linalg.norm(vertices[busy] - truth_v[busy], axis=1)
    warp_err_v = np.linalg.norm(warp_only[busy] - truth_v[busy], axis=1)
    # one colour scale for every dense-error map of the generated take (this picture and the methods'
    # comparison), set by the thin shell at its busiest frame: the warp alone goes past it (the arrow)
    error_vmax = float(np.percentile(shell_err_v, 99))
    drawn = render_side_by_side(
        [
            MeshPanel(truth_v[busy], F, None, f"ground truth, frame {busy}"),
            MeshPanel(np.asarray(vertices[busy]), F, None, "facecap (thin shell)"),
            MeshPanel(np.asarray(vertices[busy]), F, shell_err_v, "thin shell error"),
            MeshPanel(warp_only[busy], F, warp_err_v, "warp alone error"),
        ],
        pictures / "frame_comparison.png",
        value_label="error (mm)", vmin=0.0, vmax=error_vmax,
        title=f"Generated take, frame {busy} (the busiest): dense error against ground truth",
        caption=f"One colour scale here and in methods_error_comparison.png: 0 to {error_vmax:.2f} mm, the thin "
                "shell's 99th percentile at this frame; larger errors (the warp alone's neck) in the top colour.",
    )
    for frame in sorted({0, busy, worst}):
        render_mesh(np.asarray(vertices[frame]), F, pictures / f"result_frame_{frame:04d}.png",
                    title=f"facecap result, frame {frame}")
    render_mesh(scan.vertices, F, pictures / "error_mean_per_vertex.png", values=shell_error.per_vertex_mean_mm,
                value_label="mean error over the take (mm)", title="Thin shell: mean error per vertex")
    times = generated.take.times
    plot_series(times, {"thin shell (mean)": shell_error.per_frame_mean_mm,
                        "warp alone (mean)": generated.warp_error.per_frame_mean_mm,
                        "thin shell (max)": shell_error.per_frame_max_mm},
                pictures / "dense_error_over_time.png", ylabel="dense error (mm)",
                title="Dense error against ground truth")
    report = generated.result.report
    plot_series(times, {"conditioning change (RMS)": np.asarray(report["conditioning_mm"]["per_frame_rms_change"]),
                        "stabilisation residual (RMS)": np.asarray(report["stabilization_residual_mm"])},
                pictures / "marker_residuals.png", ylabel="mm",
                title="Marker conditioning: filter change and head-stabilisation residual")
    return error_vmax, {"frame_comparison.png": [drawn.vmin, drawn.vmax]}


def _said_of_generated_take(generated: _GeneratedTake) -> dict:
    """The generated take's part of ``demo_summary.json`` and its printed lines."""
    take, report = generated.take, generated.result.report
    shell_error, warp_error = generated.shell_error, generated.warp_error
    n_frames = generated.truth_vertices.shape[0]
    per_frame = ("per_frame_mean_mm", "per_frame_max_mm")
    summary = {
        "frames": n_frames, "rate_hz": take.rate, "markers": report["n_markers"],
        "vertices": report["n_vertices"],
        "thin_shell": {k: v for k, v in shell_error.to_dict().items() if k not in per_frame},
        "warp_alone": {k: v for k, v in warp_error.to_dict().items() if k not in per_frame},
        "timings": report["timings"],
    }
    lines = [
        f"generated take: {n_frames} frames at {take.rate:.0f} Hz, {report['n_markers']} markers, "
        f"{report['n_vertices']} vertices",
        f"  thin shell dense error: mean {shell_error.mean_mm:.3f} mm, p95 {shell_error.p95_mm:.3f} mm, "
        f"max {shell_error.max_mm:.3f} mm",
        f"  warp alone dense error: mean {warp_error.mean_mm:.3f} mm, p95 {warp_error.p95_mm:.3f} mm, "
        f"max {warp_error.max_mm:.3f} mm",
    ]
    return {"summary": summary, "lines": lines}


def _scan_workflow(stage: Path, case, files, shell_error, shell_vertices, error_vmax: float, progress: bool) -> dict:
    """Plan scans on the generated take, "scan" those expressions, register them and blend the take.

    The scans come from the ground truth through the scanner simulation
    (:func:`~facecap.synth.scan_expression.scan_expression`: new sampling,
    noise, holes, own frame), so the blend can be scored like the thin shell. The two methods are
    compared at a frame that was not scanned (a scanned frame is one of the blend's own bases):
    the one the plan rebuilds worst from its markers, on the colour scale ``error_vmax`` (mm)
    of ``frame_comparison.png``.
    """
    root = stage / "scans"
    root.mkdir()
    pictures = stage / "pictures"
    plan = plan_scans(files.markers, root / "plan.json", plot_path=pictures / "scan_selection.png", progress=progress)
    scan_paths = write_planned_scans(case, plan.frames, root, target_vertices=9000, first_seed=100)
    registration = register_planned_scans(root / "plan.json", files.markers, scan_paths, root / "bases",
                                          template_path=files.scan, progress=progress)
    blend_take(root / "bases", files.markers, root / "blend", progress=progress)
    blend_error = evaluate_result(files.truth, root / "blend")

    blended = np.load(root / "blend" / "vertices.npy", mmap_mode="r")
    truth_v = case.truth_vertices
    F = case.scan.faces
    unscanned = np.setdiff1d(np.arange(truth_v.shape[0]), plan.frames)
    frame = int(unscanned[np.argmax(plan.per_frame_residual[unscanned])])
    shell_err_v = np.linalg.norm(np.asarray(shell_vertices[frame]) - truth_v[frame], axis=1)
    blend_err_v = np.linalg.norm(np.asarray(blended[frame]) - truth_v[frame], axis=1)
    drawn = render_side_by_side(
        [
            MeshPanel(truth_v[frame], F, None, f"ground truth, frame {frame} (not scanned)"),
            MeshPanel(np.asarray(shell_vertices[frame]), F, shell_err_v,
                      f"thin shell (Bickel): mean {shell_err_v.mean():.2f} mm"),
            MeshPanel(np.asarray(blended[frame]), F, blend_err_v,
                      f"{len(plan.frames)} scans blended (Huang): mean {blend_err_v.mean():.2f} mm"),
        ],
        pictures / "methods_error_comparison.png",
        value_label="error (mm)", vmin=0.0, vmax=error_vmax,
        title=f"Generated take, frame {frame}: the two methods' dense error at a frame that was not scanned",
        caption=f"Scanned frames: {', '.join(map(str, plan.frames))} (at those the blend has its own scan). Frame "
                f"{frame} is the unscanned frame the {len(plan.frames)} scans rebuild worst from its markers "
                f"({plan.per_frame_residual[frame]:.2f} mm RMS).\nOne colour scale for both methods and "
                f"frame_comparison.png: 0 to {error_vmax:.2f} mm.",
    )
    plot_series(case.markers.times, {"thin shell (mean)": shell_error.per_frame_mean_mm,
                                     "scans blended (mean)": blend_error.per_frame_mean_mm},
                pictures / "methods_error_over_time.png", ylabel="dense error (mm)",
                title="Dense error against ground truth: thin shell vs blended scans")
    worst_registration = float(np.nanmax(registration["registration_mm"]))
    summary = {
        "planned_frames": [int(f) for f in plan.frames],
        "compared_frame": frame,
        "error_after_each_mm": [float(e) for e in plan.error_after_each],
        "registration_mm": registration["registration_mm"],
        "blend": {k: v for k, v in blend_error.to_dict().items() if k not in ("per_frame_mean_mm", "per_frame_max_mm")},
    }
    lines = [
        f"scan workflow: {len(plan.frames)} expressions chosen to scan (frames {', '.join(map(str, plan.frames))}), "
        f"registered to within {worst_registration:.3f} mm",
        f"  blended scans dense error: mean {blend_error.mean_mm:.3f} mm, p95 {blend_error.p95_mm:.3f} mm, "
        f"max {blend_error.max_mm:.3f} mm",
    ]
    return {"summary": summary, "lines": lines,
            "picture_ranges": {"methods_error_comparison.png": [drawn.vmin, drawn.vmax]}}


def _animate_real_take(stage: Path, sample, progress: bool) -> dict:
    """Animate the bundled ICT face from the real AnimFace take and check it without ground truth."""
    take = read_markers(bundled_path("eyebrows.c3d"))
    corr = read_correspondence(bundled_path("ict_generic_map.json"), sample.mesh)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FacecapWarning)
        result = animate_scan(sample.mesh, take, corr, stage / "animface", stabilize=True, progress=progress,
                              extra_metadata={"map": recorded_path(bundled_path("ict_generic_map.json"),
                                                                   folder=stage / "animface")})
    V = np.load(result.out_dir / "vertices.npy", mmap_mode="r")
    F = sample.mesh.faces
    n0 = igl.per_face_normals(sample.mesh.vertices, F, np.array([0.0, 0.0, 1.0]))
    flipped = 0
    step = max(1, V.shape[0] // 60)
    for t in range(0, V.shape[0], step):
        nt = igl.per_face_normals(np.asarray(V[t], dtype=np.float64), F, np.array([0.0, 0.0, 1.0]))
        flipped = max(flipped, int((np.sum(n0 * nt, axis=1) < 0).sum()))
    motion = np.linalg.norm(V - V[0], axis=2).max(axis=1)
    busiest = int(np.argmax(motion))
    pictures = stage / "pictures"
    render_mesh(np.asarray(V[busiest]), F, pictures / f"animface_frame_{busiest:04d}.png",
                values=np.linalg.norm(V[busiest] - V[0], axis=1), value_label="displacement from rest (mm)",
                title=f"Real take (AnimFace eyebrows), frame {busiest}")
    report = result.report
    plot_series(take.times, {"stabilisation residual (RMS)": np.asarray(report["stabilization_residual_mm"])},
                pictures / "animface_stabilisation.png", ylabel="mm",
                title="Real take: head-stabilisation residual of the stable markers")
    loo = report["warp_leave_one_out_mm"]
    summary = {
        "frames": take.n_frames, "markers": report["n_markers"],
        "stable_markers": json.loads((result.out_dir / "performance.json").read_text())["parameters"]["stable_markers"],
        "max_flipped_triangles_in_any_frame": flipped,
        "max_vertex_motion_mm": float(motion.max()),
        "busiest_frame": busiest,
        "warp_leave_one_out_median_mm": float(np.nanmedian(list(loo.values()))),
        "warp_outliers": report["warp_outliers"],
        "timings": report["timings"],
    }
    return {
        "summary": summary,
        "lines": [
            f"real AnimFace take: {take.n_frames} frames, {report['n_markers']} markers, "
            f"stabilised on {', '.join(summary['stable_markers'])}; flipped triangles in any frame: {flipped}; "
            f"max motion {motion.max():.1f} mm",
        ],
    }


_MUSCLE_DEMO_TETS = 3000
_MUSCLE_DEMO_FRAMES = 96


def _muscle_run(stage: Path, sample, busiest: int, progress: bool) -> dict:
    """The bundled face as an anatomical model, solved for its muscles on the real take round its busiest frame.

    A small model (``n_tets`` 3000: seconds to build, about 0.2 s a frame) and 96 frames keep the demo short;
    ``facecap build-anatomy`` defaults to about 100k tetrahedra. The take's markers reach the ICT face by
    animate's warp (``retarget='auto'`` finds that the actor's face is not the scan's). The frames lead up
    to the take's busiest one, a frown whose 15 mm brow motion is beyond what the model's corrugators reach
    (its frames are flagged ``large_residual``: the demo shows that too).

    The frown is measured, not assumed: the inner brows' distances to the inner eye corners and to each
    other in the raw take (distances between markers, so the head's motion does not enter) shrink by
    5-8 mm at the busiest frame (631). The brow lowerers (corrugators, procerus) then rise to 1, the
    solve's bound (full activation): at full strength, with the bones at rest, the model's brow markers
    move 1-4 mm where the take asks 7-9 mm down (measured on one build of this model with the forward
    solve), so the solve also turns the cranium about 2.4 degrees (which lowers the brows further) and
    5-10 mm stay on the brow markers. The solve is right within its model's reach (docs/muscles.md, "The
    reach"); the activation picture says so on its face.
    """
    folder = stage / "muscles"
    pictures = stage / "pictures"
    anatomy = build_anatomy(sample.mesh, n_tets=_MUSCLE_DEMO_TETS, progress=False)
    anatomy.save(folder / "model")
    render_anatomy_layout(anatomy, pictures / "muscles_layout.png")
    first = int(np.clip(busiest - 3 * _MUSCLE_DEMO_FRAMES // 4, 0, None))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FacecapWarning)  # the eyelid markers are off the model: expected
        done = solve_muscle_take(folder / "model", bundled_path("eyebrows.c3d"), bundled_path("ict_generic_map.json"),
                                 folder / "animface", frames=(first, first + _MUSCLE_DEMO_FRAMES),
                                 scheduler="synchronous", chunk_frames=_MUSCLE_DEMO_FRAMES, progress=progress,
                                 extra_metadata={"map": recorded_path(bundled_path("ict_generic_map.json"),
                                                                      folder=folder / "animface")})
    activity = _muscle_activity(done, list(anatomy.muscle_names), first, busiest)
    _draw_muscle_run(stage, sample, done, activity, first)
    return _said_of_muscle_run(anatomy, done.report, activity, first)


class _MuscleActivity(NamedTuple):
    """What the muscle solve of the demo did, read from its result folder."""

    names: list[str]  # the model's muscles
    frames: np.ndarray  # (T,) int64, take frames of activations.csv
    activations: np.ndarray  # (T, muscles)
    shown: int  # the row of the take's busiest frame
    strongest: list[str]  # the three most activated muscles
    at_bound: list[str]  # the muscles at full activation in some frame
    flag_counts: dict[str, int]  # frames flagged, by flag
    brows: dict  # _brow_change at the shown frame


def _muscle_activity(done, names: list[str], first: int, busiest: int) -> _MuscleActivity:
    """The solve's activations, its strongest muscles, its flags, and the brows' motion at the shown frame."""
    V = np.load(done.out_dir / "vertices.npy", mmap_mode="r")
    j = int(np.clip(busiest - first, 0, V.shape[0] - 1))
    table = np.loadtxt(done.out_dir / "activations.csv", delimiter=",", skiprows=1)
    frames, A = table[:, 0].astype(np.int64), table[:, 1:]
    strongest = [names[i] for i in np.argsort(-A.max(axis=0))[:3]]
    at_bound = [names[i] for i in np.flatnonzero(A.max(axis=0) >= 1.0 - 1e-3)]
    flag_counts: dict[str, int] = {}
    for frame_flags in done.report["flags"].values():
        for flag in frame_flags:
            flag_counts[flag] = flag_counts.get(flag, 0) + 1
    brows = _brow_change(read_markers(bundled_path("eyebrows.c3d")), first + j)
    return _MuscleActivity(names, frames, A, j, strongest, at_bound, flag_counts, brows)


def _draw_muscle_run(stage: Path, sample, done, activity: _MuscleActivity, first: int) -> None:
    """The activations over the solved frames, and the muscle face beside the thin shell's at the shown frame."""
    pictures = stage / "pictures"
    report, names, j, brows = done.report, activity.names, activity.shown, activity.brows
    lowerers = [name for name in activity.at_bound
                if name.startswith(("corrugator", "procerus", "depressor_supercilii"))]
    flag_counts = activity.flag_counts
    flagged_said = "; ".join(f"{flag}: {FRAME_FLAG_MEANINGS.get(flag, flag)}" for flag in sorted(flag_counts))
    residual = report["marker_residual_mm"]
    at_j = {label: r for label, r in zip(residual["labels"], residual["per_frame"][j]) if r is not None}
    worst_markers = sorted(at_j, key=at_j.get, reverse=True)[:4]
    performance = json.loads((done.out_dir / "performance.json").read_text())
    plot_muscle_activations(
        pictures / "muscles_activations.png", activity.frames, float(performance["rate"]), tuple(names),
        activity.activations, report, performance,
        title=f"Real take (AnimFace), frames {first}-{first + _MUSCLE_DEMO_FRAMES - 1}: muscle activations "
              f"into {brows['expression']}",
        caption=f"At frame {first + j} {brows['said']} (marker distances in the raw take).\n"
                f"{len(activity.at_bound)} muscles reach 1, full activation (the solve's bound)"
                + (f", among them the brow lowerers ({', '.join(lowerers)}): the model at full strength does not "
                   "move the brows as far as the markers do" if lowerers else "") + ".\n"
                f"Shaded: {report['frames_flagged']} of {len(activity.frames)} frames flagged ({flagged_said}); at frame "
                f"{first + j}: " + ", ".join(f"{m} {at_j[m]:.1f} mm" for m in worst_markers) + ".")
    # the solved cranium's turn (the nearest rotation to its affine part): the head the muscle face carries
    turn_deg = float(np.degrees(Rotation.from_matrix(np.load(done.out_dir / "bone_transforms.npz")["cranium"][j][:, :3])
                                .magnitude()))
    V = np.load(done.out_dir / "vertices.npy", mmap_mode="r")
    shell = np.load(stage / "animface" / "vertices.npy", mmap_mode="r")
    rest = sample.mesh.vertices
    muscle_motion = np.linalg.norm(np.asarray(V[j], np.float64) - rest, axis=1)
    shell_motion = np.linalg.norm(np.asarray(shell[first + j], np.float64) - rest, axis=1)
    render_side_by_side(
        [MeshPanel(np.asarray(shell[first + j]), sample.mesh.faces, shell_motion, "animate (thin shell)"),
         MeshPanel(np.asarray(V[j]), sample.mesh.faces, muscle_motion, "solve-muscles")],
        pictures / "muscles_frame_comparison.png", value_label="displacement from rest (mm)", vmin=0.0,
        vmax=float(np.percentile(np.concatenate([shell_motion, muscle_motion]), 99)),
        title=f"Real take (AnimFace), frame {first + j}: the thin shell and the muscle-driven face",
        caption=f"Both in the scan's frame, the take's head motion removed. The muscle face also carries its solved "
                f"cranium, turned {turn_deg:.1f} degrees here:\nthe solve tilts the head to bring the brows nearer the "
                "markers than its muscles can, hence the neck's colour.",
    )


def _said_of_muscle_run(anatomy, report: dict, activity: _MuscleActivity, first: int) -> dict:
    """The muscle run's part of ``demo_summary.json`` and its printed lines."""
    names, A, flag_counts, brows = activity.names, activity.activations, activity.flag_counts, activity.brows
    strongest = activity.strongest
    summary = {
        "frames": [first, first + _MUSCLE_DEMO_FRAMES], "tetrahedra": int(anatomy.n_tets),
        "muscles": len(names), "markers": report["n_markers"], "markers_left_out": report["markers_left_out"],
        "marker_rms_mm": report["marker_residual_mm"]["rms"],
        "marker_rms_median_frame_mm": float(np.nanmedian(np.asarray(report["marker_residual_mm"]["per_frame_rms"],
                                                                    dtype=np.float64))),
        "frames_flagged": report["frames_flagged"],
        "flags": {flag: {"frames": n, "meaning": FRAME_FLAG_MEANINGS.get(flag, flag)} for flag, n in flag_counts.items()},
        "expression": brows["said"], "muscles_at_full_activation": activity.at_bound,
        "inverted_tets_max": int(max(report["inverted_tets"])), "activation_max": float(A.max()),
        "strongest_muscles": strongest, "seconds": report["timings"]["total_s"],
    }
    return {
        "summary": summary,
        "lines": [
            f"muscles: {anatomy.n_tets} tetrahedra, {len(names)} muscles, real take frames {first}-"
            f"{first + _MUSCLE_DEMO_FRAMES - 1} from {report['n_markers']} markers: marker rms "
            f"{summary['marker_rms_mm']:.2f} mm (median frame {summary['marker_rms_median_frame_mm']:.2f}), "
            f"strongest {', '.join(strongest)} ({report['timings']['total_s']:.0f} s)",
            f"  {report['frames_flagged']} of {len(activity.frames)} frames flagged ("
            + "; ".join(f"{n} {flag}: {FRAME_FLAG_MEANINGS.get(flag, flag)}" for flag, n in sorted(flag_counts.items()))
            + (f"): {brows['expression']} beyond the model's reach" if "large_residual" in flag_counts else ")")
            + ", see pictures/muscles_activations.png",
        ],
    }


def _brow_change(take, frame: int, rest_frame: int = 0) -> dict:
    """How the inner brows moved between the rest frame and ``frame`` of the AnimFace take, from marker distances.

    Distances between markers do not see the head's motion, so no stabilisation enters: each inner
    brow's distance to its inner eye corner, and the inner brows' distance to each other. Both shrink in a
    frown (brows lowered and drawn together), the first grows in a brow raise.

    Returns
    -------
    dict
        ``expression`` ('a frown', 'a brow raise' or 'no clear brow motion'), ``said`` (the figures in
        words), ``to_eye_mm`` (left, right change), ``between_mm`` (change), negative = nearer.
    """
    P = np.asarray(take.positions, dtype=np.float64)
    index = {label: i for i, label in enumerate(take.labels)}

    def change(a: str, b: str) -> float:
        d = np.linalg.norm(P[[rest_frame, frame], index[a]] - P[[rest_frame, frame], index[b]], axis=1)
        return float(d[1] - d[0])

    to_eye = (change("Leyebrow_Inside", "Leye_Inside"), change("Reyebrow_Inside", "Reye_Inside"))
    between = change("Leyebrow_Inside", "Reyebrow_Inside")
    expression = ("a frown" if max(to_eye) < -2.0 and between < -2.0 else
                  "a brow raise" if min(to_eye) > 2.0 else "no clear brow motion")
    said = (f"{expression}: each inner brow {-to_eye[0]:.1f} and {-to_eye[1]:.1f} mm nearer its eye, the brows "
            f"{-between:.1f} mm nearer each other" if expression == "a frown" else
            f"{expression}: inner brows {to_eye[0]:+.1f} and {to_eye[1]:+.1f} mm from the eyes, {between:+.1f} mm "
            "from each other")
    return {"expression": expression, "said": said, "to_eye_mm": to_eye, "between_mm": between}


_WRINKLE_FRAME = 8
"""The mocap frame the wrinkle pictures show: the take's last, a video frame, every wrinkle at its deepest."""


def _wrinkle_layer(stage: Path, progress: bool) -> dict:
    """A 9-frame take with painted-wrinkle footage: animate, then the wrinkle layer, with its pictures.

    Video frame 0 is the neutral scan, frames 1-2 every wrinkle-making expression at once. Pictures: the
    footage with the tracked valley splines, one fitted cross-section against the observed intensities,
    and the large scale, the result with wrinkles and the truth side by side with the error heat maps.

    The large scale is ``animate`` with its defaults. The take is neutral for only its first 3 frames
    (60 ms at 50 Hz); before the rest average weighed each sample by its closeness to the rest frame, its
    0.1 s Gaussian reached 13 frames and took about half of the smile into the rest pose (the picture's
    "large scale" showed half the truth's smile; with the head also left unstabilised it was 2.8 mm off the
    truth's large scale at frame 8, now 0.86 mm, where the rest frame alone gives 0.82).
    """
    t0 = time.perf_counter()
    folder = stage / "wrinkles"
    files = write_footage_case(folder / "inputs", n_frames=9, seed=2,
                               curves=every_wrinkle_at_once(9, load_ict_sample().expression_names), progress=progress)
    scan = read_mesh(files.scan)
    take = read_markers(files.markers)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FacecapWarning)  # head-band markers not in the map: expected
        animate_scan(scan, take, read_correspondence(files.map, scan), folder / "large_scale", progress=progress)
    setup = read_camera_file(files.cameras)
    done = capture_wrinkles(folder / "large_scale", setup.cameras, files.videos, files.masks, folder / "result",
                            video_rate_hz=setup.video_rate_hz, progress=progress)
    truth = np.load(files.truth)
    A = read_result(folder / "large_scale").frames().astype(np.float64)
    W = read_result(folder / "result").frames().astype(np.float64)
    t = _WRINKLE_FRAME
    video = int(round((t - setup.first_mocap_frame) * setup.video_rate_hz / take.rate))
    true = (truth["vertices"][t] - truth["large_scale"][t]).astype(np.float64)
    added = W[t] - A[t]
    wrinkle = np.linalg.norm(true, axis=1) > 0.1
    error = np.linalg.norm(added - true, axis=1)
    ratio = float(error[wrinkle].mean() / np.linalg.norm(true, axis=1)[wrinkle].mean())
    outside = float(np.linalg.norm(added, axis=1)[~truth["wrinkle_mask"]].max())
    pictures = stage / "pictures"
    camera = setup.cameras[0]
    frame_said = f"video frame {video} = mocap frame {t} ({t / take.rate:.2f} s)"
    section = _shown_cross_section(folder, camera, files.videos[0] / f"frame_{video:06d}.png", done.out_dir, video,
                                   scan.faces, A[t], truth, t)
    _draw_cross_section(pictures / "wrinkles_cross_section.png", section, camera, frame_said)
    _draw_tracked_splines(pictures / "wrinkles_tracked_splines.png", section, camera, frame_said)
    _draw_wrinkle_frame(pictures, scan.faces, A[t], W[t], truth["vertices"][t].astype(np.float64), true, error,
                        wrinkle, ratio, t, frame_said)
    seconds = time.perf_counter() - t0
    large_scale_error = float(np.linalg.norm(A[t] - truth["large_scale"][t], axis=1).mean())
    summary = {"video_frames": done.n_video_frames, "ratio_to_adding_nothing": ratio,
               "large_scale_mean_error_mm": large_scale_error, "cross_section": {
                   "wrinkle": section.wrinkle_name, "width_mm": float(section.fit.width[section.best]),
                   "depth_mm": float(section.fit.depth[section.best]),
                   "true_width_mm": section.true_width_mm, "true_depth_mm": section.true_depth_mm},
               "outside_wrinkle_mask_max_mm": outside, "timings": done.timings, "seconds": seconds}
    lines = [f"wrinkle layer: {done.n_video_frames} video frames, 2 cameras, {scan.n_vertices} vertices",
             f"  error over the wrinkles {ratio:.2f} of adding nothing (mocap frame {t}); "
             f"outside them at most {outside:.3f} mm; {seconds:.0f} s with the footage rendered"]
    return {"summary": summary, "lines": lines}


class _CrossSection(NamedTuple):
    """The one fitted cross-section the wrinkle pictures show, in one camera's image of one video frame."""

    image: np.ndarray  # the camera's image, as stored
    doc: dict  # wrinkles.json
    video: int  # the video frame
    samples: Any  # the sampled cross-sections (fit_cross_sections)
    fit: Any  # their fits
    best: int  # the one shown
    on_truth: bool  # whether it lies on one of the truth's wrinkles
    wrinkle_name: str  # that wrinkle's name, or "(none of the truth's)"
    true_width_mm: float  # the truth's width and depth there (NaN off the truth's wrinkles)
    true_depth_mm: float


def _shown_cross_section(folder: Path, camera: Camera, image_path: Path, result_dir: Path, video: int, F: np.ndarray,
                         large_scale: np.ndarray, truth, t: int) -> _CrossSection:
    """Fit the cross-sections of the tracked wrinkles in one image; pick a typical one and find its truth."""
    image = read_image(image_path)
    doc = json.loads((result_dir / "wrinkles.json").read_text())
    correspondence = read_mocap_correspondence(folder / "large_scale" / "correspondence.npz")
    caster = RayCaster(large_scale_in_mocap(large_scale, correspondence, t), F)
    curves = [np.asarray(entry["splines_px"][camera.name]) for entry in doc["frames"][video]["wrinkles"]
              if camera.name in entry["splines_px"]]
    sections = fit_cross_sections(image, curves, camera, caster)
    fit, samples = sections.fit, sections.samples
    # a typical, well-measured cross-section: among the detected wrinkles at least as deep as their median,
    # the one the model fits best (the deepest fit is as often a profile that the paint or the outline cut
    # short, fitted by a wide shallow model)
    found = fit.has_wrinkle & np.isfinite(fit.rms)
    if not found.any():  # nothing detected: show the best-fitted profile, flat
        found = np.isfinite(fit.rms)
    deep = found & (fit.depth >= np.median(fit.depth[found]))
    best = int(np.flatnonzero(deep)[np.argmin(fit.rms[deep])])
    # which true wrinkle the cross-section lies on, and the truth there: the generator's valley lines of this
    # frame (scan frame) carried into the mocap frame and projected, the nearest point to the section's centre
    to_mocap = truth["mocap_from_scan"] @ truth["head_pose"][t]
    lines_px = camera.project(truth["curve_points"][t] @ to_mocap[:3, :3].T + to_mocap[:3, 3]).pixels
    on_line = np.linalg.norm(lines_px - samples.centres_px[best], axis=-1)
    curve, point = np.unravel_index(np.nanargmin(on_line), on_line.shape)
    on_truth = bool(on_line[curve, point] <= 10.0)  # px; farther: a valley tracked where the truth has none
    wrinkle_name = str(truth["curve_names"][curve]) if on_truth else "(none of the truth's)"
    true_w, true_d = ((float(truth["widths"][t, curve, point]), float(truth["depths"][t, curve, point])) if on_truth
                      else (float("nan"), float("nan")))
    return _CrossSection(image, doc, video, samples, fit, best, on_truth, wrinkle_name, true_w, true_d)


def _pyplot():
    """matplotlib's pyplot, drawing off screen."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _draw_cross_section(path: Path, section: _CrossSection, camera: Camera, frame_said: str) -> None:
    """The shown cross-section's observed intensities, with the shading model at the fitted and the true shape."""
    plt = _pyplot()
    fit, samples, best = section.fit, section.samples, section.best
    true_w, true_d = section.true_width_mm, section.true_depth_mm
    valid = samples.valid[best]
    p = samples.p
    fig, ax = plt.subplots(figsize=(8, 4.6), dpi=110)
    ax.plot(p[valid], samples.intensity[best, valid] / fit.ambient[best], ".", ms=3,
            label="observed intensity / unshadowed level")
    model = wedge_intensity(p - fit.offset[best], fit.width[best], fit.depth[best], rounding=DEFAULT_ROUNDING)
    ax.plot(p, model, "-", label=f"model (eq. 6) at the fitted w {fit.width[best]:.2f} mm, d {fit.depth[best]:.2f} mm")
    if section.on_truth:
        ax.plot(p, wedge_intensity(p - fit.offset[best], true_w, true_d, rounding=DEFAULT_ROUNDING), "--",
                color="0.4", lw=1.0, label=f"model (eq. 6) at the true w {true_w:.2f} mm, d {true_d:.2f} mm")
    ax.set_xlabel("distance across the valley (mm)")
    ax.set_ylabel("intensity ratio")
    ax.set_title(f"Wrinkle {section.wrinkle_name}, {camera.name}, {frame_said}:\none cross-section, its width w and "
                 "depth d fitted by eq. 7 to the shading model of eq. 6", fontsize=10)
    ax.legend(fontsize=8, loc="lower right")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", bbox_inches="tight")
    plt.close(fig)


def _draw_tracked_splines(path: Path, section: _CrossSection, camera: Camera, frame_said: str) -> None:
    """The footage with the tracked valley splines, and where the shown cross-section lies."""
    plt = _pyplot()
    image, samples, best, p = section.image, section.samples, section.best, section.samples.p
    fig, ax = plt.subplots(figsize=(11, 8.3), dpi=100)
    ax.imshow(np.clip(image.astype(np.float64) / np.iinfo(image.dtype).max / 0.8, 0, 1) ** (1 / 2.2))
    for entry in section.doc["frames"][section.video]["wrinkles"]:
        spline = entry["splines_px"].get(camera.name)
        if spline:
            P = np.asarray(spline)
            ax.plot(P[:, 0], P[:, 1], "-", color="cyan", lw=1.2)
    across = samples.centres_px[best] + np.outer([p[0], p[-1]], samples.normals_px[best]) / samples.mm_per_px[best]
    ax.plot(across[:, 0], across[:, 1], "-", color="red", lw=2.0,
            label=f"the cross-section of wrinkles_cross_section.png ({section.wrinkle_name})")
    ax.legend(loc="lower left", fontsize=9)
    ax.set_axis_off()
    ax.set_title(f"{camera.name}, {frame_said}: the tracked valley splines (eq. 5)")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", bbox_inches="tight")
    plt.close(fig)


def _draw_wrinkle_frame(pictures: Path, F: np.ndarray, large_scale: np.ndarray, with_wrinkles: np.ndarray,
                        truth: np.ndarray, true: np.ndarray, error: np.ndarray, wrinkle: np.ndarray, ratio: float,
                        t: int, frame_said: str) -> None:
    """The frame: large scale, with wrinkles, truth; and the error against adding nothing.

    Whole meshes, framed alike (the default bounds: every panel's extent), so nothing is cut at the edges.
    """
    size = np.linalg.norm(true, axis=1)
    vmax = float(np.percentile(size[wrinkle], 99))
    symbols = ("A: the large scale (animate, from the markers); W: A with the wrinkle layer; "
               "G: the truth (ground truth with wrinkles);\nL: the truth's large scale, G without its wrinkles. "
               "The true wrinkles are G - L, the ones added W - A.")
    render_side_by_side(
        [MeshPanel(large_scale, F, None, "A: large scale (animate)"), MeshPanel(with_wrinkles, F, None, "W: with wrinkles"),
         MeshPanel(truth, F, None, "G: truth")],
        pictures / "wrinkles_frame.png", title=f"{frame_said[0].upper()}{frame_said[1:]}: the wrinkle layer",
        panel_size_px=(700, 860), caption=symbols)
    render_side_by_side(
        [MeshPanel(large_scale, F, size, "adding nothing: |G - L|, the true wrinkles"),
         MeshPanel(with_wrinkles, F, error, "with wrinkles: |(W - A) - (G - L)|")],
        pictures / "wrinkles_error.png", value_label="wrinkle displacement error (mm)", vmin=0.0, vmax=vmax,
        panel_size_px=(700, 860), caption=symbols,
        title=f"Mocap frame {t}: the wrinkle displacement's error against the truth "
              f"(over the wrinkles {ratio:.2f} of adding nothing)")
