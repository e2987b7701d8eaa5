"""The ``facecap`` command line: a thin layer over the library.

Every command validates its input at the boundary; bad input prints one line
naming the file and the problem and exits with status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from typing import Any, Sequence


from . import __version__
from .errors import FacecapError, FacecapWarning

__all__ = ["main"]

EXIT_BAD_INPUT = 2


def _add_animate(sub: argparse._SubParsersAction) -> None:
    from .deform.thin_shell import DEFAULT_KB_MM2, DEFAULT_KS

    p = sub.add_parser(
        "animate",
        help="animate a face scan from a mocap take (Bickel et al. 2007, large scale)",
        description="Animate a static face scan from a facial mocap take: markers are gap-filled, "
        "optionally stabilised and filtered, mapped onto the scan by a triharmonic space warp, "
        "and drive a linear thin shell at the scan's full resolution.",
    )
    p.add_argument("--scan", required=True, help=f"face scan: {_formats_read('mesh')}")
    p.add_argument("--scan-units", default="mm",
                   help="length unit of the scan file (files do not say): mm, cm, m, in, or auto (the unit the "
                        "markers' size suggests, with a notice); a unit the markers' size contradicts stops [mm]")
    p.add_argument("--markers", required=True, help=f"mocap take: {_formats_read('take')}")
    p.add_argument("--marker-units", default=None, help="override the unit the marker file declares")
    p.add_argument("--map", required=True,
                   help=f"marker map, {_formats_read('map')}: marker label -> scan vertex index or 3D point")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--rest-frame", type=int, default=0,
                   help="the take's rest frame: stabilisation aligns to it and the warp maps it onto the scan "
                        "(its expression, if not the scan's, is measured: --rest-pose) [0]")
    p.add_argument("--ks", type=float, default=DEFAULT_KS, help=f"stretching stiffness, dimensionless [{DEFAULT_KS}]")
    p.add_argument("--kb", type=float, default=DEFAULT_KB_MM2, help=f"bending stiffness in mm^2 [{DEFAULT_KB_MM2}]")
    p.add_argument(
        "--stabilize", default="auto",
        help="remove rigid head motion: 'auto' (a head band when there is one, else the pose most "
             "markers agree on per frame, nothing on a still head), 'consensus' (that pose always), "
             "comma-separated labels of skull or head-band markers, or 'off' [auto]",
    )
    p.add_argument("--rest-pose", choices=("auto", "scan", "expression"), default="auto",
                   help="what the rest frame's mismatch with the scan is: 'scan' (the rest frame shows the scan's "
                        "expression; the warp maps it onto the scan), 'expression' (the actor rests with an "
                        "expression of their own, kept as motion), 'auto' (measured; kept, with a note, when it is "
                        "clearly above the noise, shared by neighbouring markers or along the take's own motion, and "
                        "not off marker by marker as a hand-picked map is) [auto]")
    p.add_argument("--neutral", default=None, metavar="A:B|TAKE",
                   help="an explicit neutral reference instead of the rest frame: frames A <= t < B of this take in "
                        "which the actor holds the scan's expression, or a separate neutral take file")
    p.add_argument("--no-smooth", action="store_true", help="skip the spatio-temporal bilateral filter")
    p.add_argument("--temporal-sigma", default="auto", type=_temporal_sigma,
                   help="the filter's temporal sigma in s, or 'auto': chosen for the take by cross-validation [auto]")
    p.add_argument("--marker-offset", type=float, default=1.5,
                   help="marker centre height above the skin, mm; 0: markers on the skin (the paper) [1.5]")
    p.add_argument("--rest-average", type=float, default=0.1,
                   help="the warp's rest markers: Gaussian average round --rest-frame, sigma in s; 0: that frame alone [0.1]")
    _add_output_options(p)
    _add_overwrite(p)
    p.add_argument("--unmarked-pieces", choices=("carry", "rigid"), default="carry",
                   help="pieces with no marker (eyes, teeth): follow the nearest marked surface, or stay [carry]")
    p.add_argument("--batch-frames", type=int, default=32, help="frames per dense product [32]")
    p.add_argument("--precision", choices=("float32", "int16"), default="float32",
                   help="arithmetic of the per-frame product: exact float32, or int16 fixed point "
                        "(about 1.5x faster with MKL on AVX-512 VNNI, error ~1e-4 of the motion) [float32]")
    p.set_defaults(func=_cmd_animate)


def _cmd_animate(args: argparse.Namespace) -> int:
    from .pipelines.animate_scan import animate_scan
    from .io.read_correspondence import read_correspondence
    from .io.read_markers import read_markers
    from .io.read_mesh import read_mesh
    from .io.atomic_write import recorded_path
    from .io.write_performance import check_result_destination
    from .markers.check_take_units import check_take_units

    check_result_destination(args.out, overwrite=args.overwrite)  # before reading anything
    auto = args.scan_units.strip().lower() == "auto"
    scan = read_mesh(args.scan, unit=None if auto else args.scan_units)
    take = read_markers(args.markers, unit=args.marker_units)
    corr = read_correspondence(args.map, scan)
    if auto:
        scan = check_take_units(scan, take, corr, rest_frame=args.rest_frame, convert=True)
    stabilize = _stabilize_option(args.stabilize)
    if args.batch_frames < 1:
        raise FacecapError(f"--batch-frames: expected a positive integer, got {args.batch_frames}")
    neutral = _neutral_option(args.neutral, take, args.marker_units)
    result = animate_scan(
        scan, take, corr, args.out,
        rest_frame=args.rest_frame, ks=args.ks, kb=args.kb, stabilize=stabilize,
        smooth=not args.no_smooth, temporal_sigma_s=args.temporal_sigma, marker_offset_mm=args.marker_offset,
        rest_average_s=args.rest_average, rest_pose=args.rest_pose, neutral=neutral, **_output_options(args), unmarked_pieces=args.unmarked_pieces,
        batch_frames=args.batch_frames, precision=args.precision, progress=not args.quiet,
        extra_metadata={"map": recorded_path(args.map, folder=args.out)}, overwrite=args.overwrite,
    )
    if not args.quiet:
        t = result.report["timings"]
        speed = (f"{t['frames_per_second']:.0f} frames/s" if t.get("frames_per_second")
                 else "no frame computed: the rig is the result")
        print(
            f"wrote {result.out_dir}: {result.report['n_frames']} frames x {result.report['n_vertices']} vertices "
            f"from {result.report['n_markers']} markers (set-up {t['shell_setup_s']:.1f} s, {speed})"
        )
        # what a warning line already said (a choice made for the user) is not said twice
        warned = " ".join(result.report["warnings"])
        head = result.report["head_motion"]
        if head["stabilized"] or head["mode"] == "off":
            print(_head_motion_line(head))
        if result.report["rest_pose"]["reason"] not in warned:
            print(f"rest frame: {result.report['rest_pose']['reason']}")
        if result.report["warp_outliers"]:
            print(f"check these markers' scan vertices (large leave-one-out warp residual): "
                  f"{', '.join(result.report['warp_outliers'])}")
    return 0


def _head_motion_line(head: dict) -> str:
    """One line on the head motion a run found and removed (``report.json``'s ``head_motion``)."""
    if not head["stabilized"]:
        return ("head motion: left as captured" + (" (--stabilize off)" if head["mode"] == "off" else
                " (the head does not move beyond what the expressions move the markers by)"))
    line = (f"head motion: removed, up to {head['max_rotation_deg']:.1f} degrees and {head['max_translation_mm']:.1f} mm, "
            f"pose from the {head['pose_from']}")
    if head["stable_markers"]:
        line += f" (rigid set: {', '.join(head['stable_markers'])})"
    return line


def _neutral_option(text: str | None, take: Any, marker_units: str | None) -> Any:
    """``--neutral``: a frame range ``A:B`` of the take, or a neutral take file (read with the take's unit option)."""
    if text is None:
        return None
    from pathlib import Path

    from .deform.rest_pose import parse_frame_range
    from .io.read_markers import MARKER_FORMATS, read_markers

    # a take file's name may hold a colon too (a Windows drive, C:\takes\neutral.c3d): a name with a take's
    # suffix is read as a file, so that a missing one is reported as missing, not as a bad range
    if ":" in text and not Path(text).exists() and Path(text).suffix.lower() not in MARKER_FORMATS:
        return parse_frame_range(text, take.n_frames)
    return read_markers(text, unit=marker_units)


def _add_info(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "info", help="what a take, a mesh or a result folder holds",
        description="What a take, a mesh or a result folder holds, with a warning where a mesh or take has a size "
        "no face has (and the length unit that would give it one).",
    )
    p.add_argument("file", help=f"a take: {_formats_read('take')}; a mesh: {_formats_read('mesh')}; "
                                f"a facecap result folder; or a marker map, {_formats_read('map')}, with --scan and "
                                "--markers")
    p.add_argument("--units", default=None,
                   help="length unit of the file: mm, cm, m or in; a mesh file states none [mm], a take's own is "
                        "overridden [the take's]")
    p.add_argument("--labels", action="store_true", help="list every marker label of a take, with its gaps")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    check = p.add_argument_group("checking a marker map (FILE is the map)")
    check.add_argument("--scan", default=None, help=f"the scan the map refers to: {_formats_read('mesh')}")
    check.add_argument("--scan-units", default="mm", help="length unit of the scan file [mm]")
    check.add_argument("--markers", default=None, help=f"the take the map is for: {_formats_read('take')}")
    check.add_argument("--rest-frame", type=int, default=0, help="frame whose expression is nearest the scan's [0]")
    check.add_argument("--marker-offset", type=float, default=1.5, help="marker centre height above the skin, mm [1.5]")
    p.set_defaults(func=_cmd_info)


def _cmd_info(args: argparse.Namespace) -> int:
    from .report.describe import describe_file, format_description

    if args.scan is not None or args.markers is not None or args.file.lower().endswith(".json"):
        return _check_map(args)
    info = describe_file(args.file, unit=args.units)
    if args.json:
        print(json.dumps(info, indent=2))
    else:
        print(format_description(info, labels=args.labels))
    return 0


def _check_map(args: argparse.Namespace) -> int:
    """``facecap info MAP --scan SCAN --markers TAKE``: a marker map checked against its take."""
    from .io.read_correspondence import read_correspondence
    from .io.read_markers import read_markers
    from .io.read_mesh import read_mesh
    from .registration.check_marker_map import check_marker_map

    if args.scan is None or args.markers is None:
        raise FacecapError(f"{args.file}: a marker map is checked against its scan and take: pass --scan SCAN "
                           "and --markers TAKE")
    scan = read_mesh(args.scan, unit=args.scan_units)
    take = read_markers(args.markers)
    corr = read_correspondence(args.file, scan)
    report = check_marker_map(scan, take, corr, rest_frame=args.rest_frame, marker_offset_mm=args.marker_offset)
    if args.json:
        print(json.dumps({k: v for k, v in report.items() if k != "summary"}, indent=2))
    else:
        print("\n".join(report["summary"]))
    return 0


def _add_map(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "map", help="find each marker's place on the scan (writes map.json, with a report and a picture)",
        description="Find where each marker of a take sits on a face scan, with no hand-picked vertices: the rest "
        "frame's markers are aligned to the scan's surface by a global search and snapped to the skin under them. "
        "Writes the map (points on the scan in its file's unit) and, beside it, a report and a labelled picture "
        "(--out map.json: map_report.json, map.png). Markers off the skin (a head band), over a hole or past the "
        "scan's rim are left out and named; docs/own_data.md explains every line.",
    )
    p.add_argument("--scan", required=True, help=f"face scan: {_formats_read('mesh')}")
    p.add_argument("--scan-units", default="mm",
                   help="length unit of the scan file (files do not say): mm, cm, m, in, or auto (the unit the "
                        "markers' size suggests, with a notice) [mm]")
    p.add_argument("--markers", required=True, help=f"mocap take: {_formats_read('take')}")
    p.add_argument("--marker-units", default=None, help="override the unit the marker file declares")
    p.add_argument("--rest-frame", type=int, default=0, help="frame whose expression is nearest the scan's [0]")
    p.add_argument("--marker-offset", type=float, default=1.5,
                   help="marker centre height above the skin, mm [1.5]")
    p.add_argument("--landmarks", default=None,
                   help="a few markers' places on the scan, in map.json's own format (label -> vertex index or "
                        "point), at least 3: they fix the pose instead of the global search")
    p.add_argument("--out", required=True, help="the map file to write, e.g. map.json")
    _add_overwrite(p, "an existing map, report or picture")
    p.set_defaults(func=_cmd_map)


def _cmd_map(args: argparse.Namespace) -> int:
    from .io.read_correspondence import read_correspondence
    from .io.read_markers import read_markers
    from .io.read_mesh import read_mesh
    from .pipelines.map_markers import map_markers

    auto = args.scan_units.strip().lower() == "auto"
    scan = read_mesh(args.scan, unit=None if auto else args.scan_units)
    take = read_markers(args.markers, unit=args.marker_units)
    landmarks = None if args.landmarks is None else read_correspondence(args.landmarks, scan)
    report = map_markers(scan, take, args.out, rest_frame=args.rest_frame, marker_offset_mm=args.marker_offset,
                         landmarks=landmarks, convert_scan_units=auto, overwrite=args.overwrite)
    if not args.quiet:
        print("\n".join(report["summary"]))
    return 0


def _colour_alignment(choice: str) -> bool | None:
    """``--color-alignment`` as the jobs take it: None (auto), True or False."""
    return {"auto": None, "on": True, "off": False}[choice]


def _formats_read(kind: str) -> str:
    """The formats facecap reads for one kind of file, as help text, from the reader's own list.

    ``kind`` is ``'mesh'``, ``'take'`` or ``'map'``; each format is named with its
    suffixes, e.g. ``'OBJ (.obj), PLY (.ply), glTF (.glb, .gltf)'``.
    """
    from .io.read_correspondence import MAP_FORMATS
    from .io.read_markers import MARKER_FORMATS
    from .io.read_mesh import MESH_FORMATS

    formats = {"mesh": MESH_FORMATS, "take": MARKER_FORMATS, "map": MAP_FORMATS}[kind]
    suffixes: dict[str, list[str]] = {}
    for suffix, name in formats.items():
        suffixes.setdefault(name, []).append(suffix)
    return ", ".join(f"{name} ({', '.join(found)})" for name, found in suffixes.items())


def _add_evaluate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("evaluate", help="dense error of a result against ground truth")
    p.add_argument("--truth", required=True, help="ground truth .npz (as written by facecap's generator)")
    p.add_argument("--result", required=True, help="a facecap output folder")
    p.add_argument("--frame", choices=("auto", "world", "stabilized"), default="auto",
                   help="compare a stabilised result in the world (moved by its head motion) or as the "
                        "stabilised face against the expression-only truth [auto: world when head_motion.npy exists]")
    p.add_argument("--region", default=None,
                   help="evaluate only these vertices (e.g. the part of the face the scans saw): a .npy bool mask "
                        "or a JSON list of vertex indices [all]")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.set_defaults(func=_cmd_evaluate)


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from .report.evaluate_result import evaluate_result

    mask = None
    if args.region is not None:
        from .io.read_region_mask import read_region_mask
        from .io.read_result import read_result

        mask = read_region_mask(args.region, read_result(args.result).n_vertices)
    error = evaluate_result(args.truth, args.result, frame=args.frame, vertex_mask=mask)
    summary = error.to_dict()
    summary.pop("per_frame_mean_mm", None)
    summary.pop("per_frame_max_mm", None)
    if args.json:
        print(json.dumps(summary, indent=2))
        return 0
    print(
        f"dense error over {summary['n_frames']} frames x {summary['n_vertices']} vertices: "
        f"mean {summary['mean_mm']:.3f} mm, p95 {summary['p95_mm']:.3f} mm, max {summary['max_mm']:.3f} mm "
        f"(mean {summary['mean_pct']:.3f}%, p95 {summary['p95_pct']:.3f}%, max {summary['max_pct']:.3f}% "
        f"of the {summary['diagonal_mm']:.1f} mm bounding-box diagonal)"
    )
    if summary.get("across_mean_mm") is not None:
        print(f"  across the skin (along the truth's normals) {summary['across_mean_mm']:.3f} mm, "
              f"along it {summary['along_mean_mm']:.3f} mm (means of each error's two parts)")
    for name, region in (summary.get("regions") or {}).items():
        print(f"  {name:>12}: mean {region['mean_mm']:.3f} mm, p95 {region['p95_mm']:.3f} mm, max {region['max_mm']:.3f} mm")
    return 0


def _add_overwrite(p: argparse.ArgumentParser, what: str = "an earlier result in --out") -> None:
    """``--overwrite``: without it a command refuses, before any work, to replace what is there."""
    p.add_argument("--overwrite", action="store_true",
                   help=f"replace {what} (without it the command stops at once, changing nothing; a folder that "
                        "is not a facecap result is never replaced)")


def _add_export_frame(p: argparse.ArgumentParser) -> None:
    """``--export-frame``: what the point caches and Alembic hold."""
    p.add_argument("--export-frame", choices=("stabilized", "world"), default="stabilized",
                   help="point caches (mdd, pc2) and Alembic: the stabilised face, or the face in the world with the "
                        "head motion baked in (written as performance_world.*) [stabilized]")


def _add_output_options(p: argparse.ArgumentParser) -> None:
    """What a command that writes a result writes: exports, vertices.npy, the rig's precision."""
    from .io.result_layout import EXPORT_FORMATS
    from .pipelines.export_result import DEFAULT_GLTF_TARGETS, DEFAULT_REVIEW_VERTICES

    p.add_argument("--export", default="", help=f"exports, comma-separated: {', '.join(EXPORT_FORMATS)}")
    _add_export_frame(p)
    p.add_argument("--no-vertices", action="store_true",
                   help="leave out vertices.npy: the result is the exact compact rig (rig/) alone")
    p.add_argument("--rig-precision", choices=("float32", "int16"), default="float32",
                   help="storage of the rig's basis: float32 (exact) or int16 (half the size, bound in rig/rig.json) "
                        "[float32]")
    p.add_argument("--gltf-targets", type=int, default=DEFAULT_GLTF_TARGETS,
                   help=f"most morph targets of the glTF export (principal components beyond) [{DEFAULT_GLTF_TARGETS}]")
    p.add_argument("--review-vertices", type=int, default=DEFAULT_REVIEW_VERTICES,
                   help=f"most vertices of the glTF review mesh (decimated beyond) [{DEFAULT_REVIEW_VERTICES}]")
    p.add_argument("--usd-shapes", default="auto", type=_usd_shapes_option,
                   help="blend shapes of the USD rig: exact, a count (principal components), or auto "
                        "(exact up to 1 GiB of shapes) [auto]")


def _output_options(args: argparse.Namespace) -> dict:
    """The keyword arguments of :func:`_add_output_options`' options, checked before any long work."""
    from .io.result_layout import parse_export_formats

    if args.gltf_targets < 1 or args.review_vertices < 3:
        raise FacecapError("--gltf-targets and --review-vertices: expected positive counts")
    return {
        "exports": parse_export_formats(args.export),
        "write_vertices": not args.no_vertices,
        "rig_precision": args.rig_precision,
        "export_options": {"gltf_targets": args.gltf_targets, "review_vertices": args.review_vertices,
                           "usd_shapes": args.usd_shapes, "export_frame": args.export_frame},
    }


def _usd_shapes_option(text: str) -> str | int:
    if text in ("auto", "exact"):
        return text
    try:
        count = int(text)
    except ValueError:
        count = 0
    if count < 1:
        raise argparse.ArgumentTypeError(f"expected 'auto', 'exact' or a positive count, got {text!r}")
    return count


def _add_view(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("view", help="review a result in the browser (writes review.html and report.html, serves them)")
    p.add_argument("result", help="a facecap result folder")
    p.add_argument("--truth", default=None, help="ground truth .npz: show the error heat map")
    p.add_argument("--frame", choices=("auto", "world", "stabilized"), default="auto",
                   help="how a stabilised result meets the truth, as for evaluate [auto]")
    p.add_argument("--port", type=int, default=0, help="localhost port [a free one]")
    p.add_argument("--no-serve", action="store_true", help="write the pages and stop")
    p.set_defaults(func=_cmd_view)


def _cmd_view(args: argparse.Namespace) -> int:
    from .report.review_page import serve
    from .pipelines.view_result import view_result

    if not 0 <= args.port <= 65535:
        raise FacecapError(f"--port: expected 0..65535, got {args.port}")
    page = view_result(args.result, truth=args.truth, frame=args.frame, progress=not args.quiet)
    if args.no_serve:
        if not args.quiet:
            print(f"wrote {page} and {page.with_name('report.html')}")
        return 0
    serve(page.parent, port=args.port, page=page.name, block=True, quiet=args.quiet)
    return 0


def _add_export(sub: argparse._SubParsersAction) -> None:
    from .io.result_layout import EXPORT_FORMATS

    p = sub.add_parser("export", help="export a finished result to other formats")
    p.add_argument("result", help="a facecap result folder")
    p.add_argument("--format", required=True, help=f"comma-separated: {', '.join(EXPORT_FORMATS)}")
    p.add_argument("--out", default=None, help="folder to write into [the result folder]")
    p.add_argument("--gltf-targets", type=int, default=None, help="most morph targets of the glTF [64]")
    p.add_argument("--review-vertices", type=int, default=None, help="most vertices of the glTF review mesh [100000]")
    p.add_argument("--usd-shapes", default=None, type=_usd_shapes_option,
                   help="blend shapes of the USD rig: exact, a count, or auto [auto]")
    _add_export_frame(p)
    _add_overwrite(p, "export files that exist already (an export otherwise only adds files)")
    p.set_defaults(func=_cmd_export)


def _cmd_export(args: argparse.Namespace) -> int:
    from .io.result_layout import parse_export_formats
    from .pipelines.export_result import export_result
    from .io.read_result import read_result

    formats = parse_export_formats(args.format)
    result = read_result(args.result)
    options = {k: v for k, v in (("gltf_targets", args.gltf_targets), ("review_vertices", args.review_vertices),
                                 ("usd_shapes", args.usd_shapes)) if v is not None}
    report = export_result(result, formats, out_dir=args.out, progress=not args.quiet, export_frame=args.export_frame,
                           overwrite=args.overwrite, **options)
    if not args.quiet:
        for fmt, entry in report.items():
            sizes = ", ".join(f"{name} ({size / 1e6:.1f} MB)" if isinstance(size, int) and not name.endswith("/")
                              else name for name, size in entry.get("files", {}).items())
            print(f"{fmt}: {sizes}")
    return 0


def _temporal_sigma(text: str) -> str | float:
    if text == "auto":
        return text
    try:
        seconds = float(text)
    except ValueError:
        seconds = -1.0
    if not (seconds >= 0 and seconds < float("inf")):
        raise argparse.ArgumentTypeError(f"expected 'auto' or a non-negative number of seconds, got {text!r}")
    return seconds


def _stabilize_option(value: str) -> bool | str | list[str]:
    if value in ("off", "none", "no"):
        return False
    if value == "auto":
        return True
    if value == "consensus":
        return "consensus"
    return [s.strip() for s in value.split(",") if s.strip()]


def _add_scan_commands(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("plan-scans", help="choose the fewest expressions to scan (Huang et al. 2011, Alg. 1)")
    p.add_argument("--markers", required=True, help=f"mocap take: {_formats_read('take')}")
    p.add_argument("--tolerance", type=float, default=0.003,
                   help="reconstruction tolerance, fraction of the marker bounding-box diagonal [0.003]")
    p.add_argument("--max-scans", type=int, default=None, help="stop after this many scans")
    p.add_argument("--rest-frame", type=int, default=0, help="frame stabilisation aligns to [0]")
    p.add_argument("--stabilize", default="auto",
                   help="'auto', 'consensus' (no head band: the pose most markers agree on), 'off' or "
                        "comma-separated labels [auto]")
    p.add_argument("--out", required=True, help="plan.json to write (the plot goes beside it)")
    _add_overwrite(p, "an existing plan (--out, its .png and .conditioned.npz)")
    p.set_defaults(func=_cmd_plan_scans)

    p = sub.add_parser("register-scans", help="register one scan per planned frame into one topology")
    p.add_argument("--plan", required=True, help="plan.json from plan-scans")
    p.add_argument("--markers", required=True, help=f"the take the plan was made from: {_formats_read('take')}")
    p.add_argument("--scans", required=True, nargs="+",
                   help=f"one scan per planned frame, in the plan's order: {_formats_read('mesh')}")
    p.add_argument("--scan-units", default="mm", help="length unit of the scan files: mm, cm, m, in or auto [mm]")
    p.add_argument("--template", default=None,
                   help=f"mesh giving the output topology (default: the first scan): {_formats_read('mesh')}")
    p.add_argument("--template-units", default="mm", help="length unit of the template file: mm, cm, m, in or auto [mm]")
    p.add_argument("--marker-offset", type=float, default=1.5, help="marker centre height above the skin, mm [1.5]")
    p.add_argument("--template-texture", default=None,
                   help="a coloured scan of the template's expression (e.g. the neutral's own scan), in the "
                        "template's units: the skin colour the scans are aligned to (default: the template's own "
                        f"texture or vertex colours); {_formats_read('mesh')}")
    p.add_argument("--color-alignment", nargs="?", const="on", default="auto", choices=("auto", "on", "off"),
                   help="slide the registrations along the scans until the skin colours match the template's: "
                        "auto (on when every scan and the template or --template-texture have a colour texture), "
                        "on (vertex colours too), off [auto]")
    p.add_argument("--refine", action="store_true",
                   help="run the fine-scale (optical flow) registration of section 6.2 (experimental)")
    p.add_argument("--workers", type=int, default=None,
                   help="processes registering scans side by side [every core when the scans hold 200,000 "
                        "vertices or more in all, else 1]")
    p.add_argument("--out", required=True, help="bases folder")
    _add_overwrite(p, "an earlier bases folder in --out")
    p.set_defaults(func=_cmd_register_scans)

    p = sub.add_parser("blend", help="reconstruct a take from registered bases (NNLS blendshapes)")
    p.add_argument("--bases", required=True, help="bases folder from register-scans")
    p.add_argument("--markers", required=True, help=f"mocap take: {_formats_read('take')}")
    _add_output_options(p)
    p.add_argument("--out", required=True, help="output folder")
    _add_overwrite(p)
    p.set_defaults(func=_cmd_blend)

    p = sub.add_parser("scans-pipeline", help="plan-scans, register-scans and blend in one go (scans exist)")
    p.add_argument("--markers", required=True, help=f"mocap take: {_formats_read('take')}")
    p.add_argument("--scans", required=True, nargs="+",
                   help=f"one scan per planned frame, in the plan's order: {_formats_read('mesh')}")
    p.add_argument("--plan", default=None, help="an existing plan.json (default: plan now and expect matching scans)")
    p.add_argument("--tolerance", type=float, default=0.003)
    p.add_argument("--scan-units", default="mm")
    p.add_argument("--template", default=None,
                   help=f"mesh giving the output topology (default: the first scan): {_formats_read('mesh')}")
    p.add_argument("--template-units", default="mm")
    p.add_argument("--marker-offset", type=float, default=1.5)
    p.add_argument("--template-texture", default=None,
                   help=f"coloured scan of the template's expression: {_formats_read('mesh')}")
    p.add_argument("--color-alignment", nargs="?", const="on", default="auto", choices=("auto", "on", "off"),
                   help="slide by skin colour: auto (when the scans and template have colour textures), on, off [auto]")
    p.add_argument("--refine", action="store_true", help="fine-scale registration (experimental)")
    p.add_argument("--workers", type=int, default=None,
                   help="processes registering scans side by side [every core when the scans hold 200,000 "
                        "vertices or more in all, else 1]")
    _add_output_options(p)
    p.add_argument("--out", required=True, help="output folder (holds plan.json, bases/, animation/)")
    _add_overwrite(p, "an earlier plan.json, bases/ and animation/ in --out")
    p.set_defaults(func=_cmd_scans_pipeline)


def _cmd_plan_scans(args: argparse.Namespace) -> int:
    from pathlib import Path

    from .pipelines.plan_scans import plan_scans

    out = Path(args.out)
    plan = plan_scans(args.markers, out, tolerance=args.tolerance, max_frames=args.max_scans,
                      rest_frame=args.rest_frame, stabilize=_stabilize_option(args.stabilize),
                      plot_path=out.with_suffix(".png"), progress=not args.quiet, overwrite=args.overwrite)
    if not args.quiet:
        print(f"wrote {out}: scan {len(plan.frames)} expressions, frames {', '.join(map(str, plan.frames))} "
              f"(markers rebuilt to {plan.worst_frame_after_each[-1]:.3f} mm in the worst frame, "
              f"{plan.error_after_each[-1]:.3f} mm RMS; tolerance {plan.tolerance_mm:.3f} mm"
              f"{'' if plan.converged else ', not met'})")
    return 0


def _cmd_register_scans(args: argparse.Namespace) -> int:
    from .pipelines.register_planned_scans import register_planned_scans

    report = register_planned_scans(args.plan, args.markers, args.scans, args.out, template_path=args.template,
                                    scan_unit=args.scan_units, template_unit=args.template_units,
                                    marker_offset_mm=args.marker_offset, refine=args.refine,
                                    template_texture_path=args.template_texture,
                                    align_colors=_colour_alignment(args.color_alignment), workers=args.workers,
                                    progress=not args.quiet, overwrite=args.overwrite)
    if not args.quiet:
        reg = report["registration_mm"]
        print(f"wrote {args.out}: {len(reg)} bases, registration residual mean {sum(reg) / len(reg):.3f} mm, "
              f"max {max(reg):.3f} mm; flagged: {report['flagged'] or 'none'}")
    return 0


def _cmd_blend(args: argparse.Namespace) -> int:
    from .pipelines.blend_take import blend_take

    report = blend_take(args.bases, args.markers, args.out, **_output_options(args), progress=not args.quiet,
                        overwrite=args.overwrite)
    if not args.quiet:
        print(f"wrote {args.out}: {report['n_frames']} frames from {report['n_bases']} bases, "
              f"marker residual mean {report['marker_residual_mm']['mean']:.3f} mm")
    return 0


def _cmd_scans_pipeline(args: argparse.Namespace) -> int:
    from pathlib import Path

    from .pipelines.run_scan_workflow import run_scan_workflow

    report = run_scan_workflow(args.markers, args.scans, args.out, plan_path=args.plan, tolerance=args.tolerance,
                               scan_unit=args.scan_units, template_path=args.template,
                               template_unit=args.template_units, marker_offset_mm=args.marker_offset,
                               template_texture_path=args.template_texture,
                               align_colors=_colour_alignment(args.color_alignment), refine=args.refine,
                               workers=args.workers, **_output_options(args), progress=not args.quiet,
                               overwrite=args.overwrite)
    if not args.quiet:
        print(f"wrote {Path(args.out)}: plan.json, bases/, animation/ ({report['n_frames']} frames)")
    return 0


def _add_synth(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("synth", help="generate a capture case with dense ground truth (and wrinkle footage)")
    p.add_argument("--out", required=True, help="folder to write (scan.obj, take.c3d, map.json, truth.npz)")
    p.add_argument("--seed", type=int, default=0, help="the take, markers, noise (and wrinkles, skin, sensor) [0]")
    p.add_argument("--frames", type=int, default=300, help="mocap frames [300]")
    p.add_argument("--identity", type=int, default=0,
                   help="0: the ICT generic face; K >= 1: a random ICT identity drawn from seed K [0]")
    p.add_argument("--footage", action="store_true",
                   help="wrinkles on a subdivided scan, filmed by two calibrated cameras at 12.5 fps (mocap at 50 Hz): "
                        "cameras.json, OpenCV calibration files, image folders, paint masks, wrinkle truth")
    p.add_argument("--levels", type=int, default=2,
                   help="with --footage: subdivisions of the scan (2: 148k vertices, 0.94 mm forehead edges; "
                        "3: 590k, 0.47 mm) [2]")
    p.add_argument("--render-edge", type=float, default=None, metavar="MM",
                   help="with --footage: render from the scan refined around the wrinkles to this edge length, so "
                        "the images shade the truth's valleys, not their sampling at the scan's vertices "
                        "(about 8 s per video frame at the default scan); 0: render the scan itself [0.3]")
    p.add_argument("--detail", action="store_true",
                   help="with --footage: footage for the detail layer instead (shape from shading): fine lines and skin "
                        "bumps on a scan refined to 0.3 mm where the lines are, studio lights (lights.json) with cast "
                        "shadows and a view-dependent specular, freckles, moles, a flush, markers drawn, no paint, 25 fps")
    p.add_argument("--appearance", choices=("phong", "independent"), default="phong",
                   help="with --detail: the Phong skin, or the held-out microfacet skin with other lights and line "
                        "profiles [phong]")
    _add_overwrite(p, "an earlier case in --out")
    p.set_defaults(func=_cmd_synth)


def _cmd_synth(args: argparse.Namespace) -> int:
    from .pipelines.generate_capture_case import generate_capture_case

    if args.frames < 2:
        raise FacecapError(f"--frames: expected at least 2, got {args.frames}")
    if args.identity < 0:
        raise FacecapError(f"--identity: expected 0 or a positive seed, got {args.identity}")
    if args.levels != 2 and not args.footage:
        raise FacecapError("--levels: only with --footage (the case without footage is on the ICT face itself)")
    if args.render_edge is not None and not args.footage:
        raise FacecapError("--render-edge: only with --footage (it is how the footage is rendered)")
    if args.detail and not args.footage:
        raise FacecapError("--detail: only with --footage (it is a kind of footage)")
    if args.appearance != "phong" and not args.detail:
        raise FacecapError("--appearance: only with --footage --detail")
    if args.detail and args.render_edge is not None:
        raise FacecapError("--render-edge: not with --detail (its scan is refined to 0.3 mm where the lines are)")
    edge = None
    if args.footage:  # the renderer's module, only for footage
        from .synth.write_footage_case import MIN_RENDER_EDGE_MM, RENDER_EDGE_MM

        if args.render_edge and not MIN_RENDER_EDGE_MM <= args.render_edge < float("inf"):
            raise FacecapError(f"--render-edge: expected 0 (off) or a finite length of at least "
                               f"{MIN_RENDER_EDGE_MM:g} mm, got {args.render_edge:g}")
        # 0 renders the scan itself; write_footage_case refuses a length it cannot render, naming it
        edge = RENDER_EDGE_MM if args.render_edge is None else (None if args.render_edge == 0 else args.render_edge)
    generate_capture_case(args.out, n_frames=args.frames, seed=args.seed, identity_seed=args.identity,
                          footage=args.footage, levels=args.levels, render_edge_mm=edge, progress=not args.quiet,
                          overwrite=args.overwrite, detail=args.detail, appearance=args.appearance)
    if not args.quiet:
        kind = f"detail footage ({args.appearance}) from two cameras" if args.detail else "wrinkle footage from two cameras"
        print(f"wrote {args.out}: {args.frames} frames" + (f", {kind}" if args.footage else ""))
    return 0


def _add_wrinkles(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "wrinkles",
        help="add expression wrinkles from painted-wrinkle footage to an animate result (Bickel et al. 2007, 5)",
        description="Track the painted wrinkles in each camera, fit their cross-sections from self-shadowing, "
        "and synthesise them on the large-scale result with the nonlinear discrete shell, video frame by video "
        "frame on the frame runner; writes a result folder like animate's plus wrinkles.json.",
    )
    p.add_argument("--result", required=True,
                   help="the large scale: a facecap animate (or facecap blend) result folder")
    p.add_argument("--cameras", required=True, nargs="+",
                   help="the facecap camera file (cameras.json), or one OpenCV calibration YAML per camera in --video order")
    p.add_argument("--video", required=True, nargs="+", help="one image folder or video file per camera")
    p.add_argument("--masks", required=True, nargs="+",
                   help="one paint mask of the first video frame per camera (label PNG or binary mask), in --video order")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--video-rate", type=float, default=None, help="footage rate in Hz [the camera file's]")
    p.add_argument("--first-mocap-frame", type=float, default=None,
                   help="mocap frame of video frame 0 [the camera file's, else 0]")
    p.add_argument("--depth-scale", type=float, default=1.0, help="scale every wrinkle's depth [1.0]")
    p.add_argument("--edits", default=None,
                   help="JSON edit file: depth scales per wrinkle and frame range, wrinkles drawn as curves or SVG "
                        "paths in a camera image (docs/wrinkles.md, Editing)")
    p.add_argument("--camera-units", default="mm", help="unit of T in OpenCV calibration files [mm]")
    p.add_argument("--scheduler", default=None,
                   help="Dask scheduler address for an existing cluster; 'local' for a local cluster of --workers "
                        "processes [run in this process]")
    p.add_argument("--workers", type=int, default=2, help="processes of a local cluster [2]")
    p.add_argument("--work", default=None, help="resumable work folder (kept; a rerun resumes) [a temporary one]")
    p.add_argument("--per-frame-projection", action="store_true",
                   help="cast every frame's splines onto that frame's mesh (the paper) instead of carrying the "
                        "first frame's lines with the skin")
    p.add_argument("--min-face-in-view", type=float, default=0.05, metavar="SHARE",
                   help="refuse a camera that sees less of the face's vertices at video frame 0 (a calibration "
                        "not of this stage); 0 for a close-up camera on a small part of a large scan [0.05]")
    p.add_argument("--export", default="", help="exports, comma-separated, as for animate")
    _add_export_frame(p)
    _add_overwrite(p)
    p.set_defaults(func=_cmd_wrinkles)


def _cmd_wrinkles(args: argparse.Namespace) -> int:
    from .cameras import read_footage_cameras
    from .io.result_layout import parse_export_formats
    from .pipelines import capture_wrinkles

    if len(args.masks) != len(args.video):
        raise FacecapError(f"--masks: {len(args.masks)} masks for {len(args.video)} footage (one per camera)")
    if args.depth_scale < 0 or args.workers < 1:
        raise FacecapError("--depth-scale must be >= 0 and --workers >= 1")
    edits = None
    if args.edits is not None:
        from .wrinkles import read_wrinkle_edits

        edits = read_wrinkle_edits(args.edits)  # before any long work
    cameras, rate, first = read_footage_cameras(args.cameras, args.video, unit=args.camera_units)
    rate = args.video_rate if args.video_rate is not None else rate
    if rate is None:
        raise FacecapError("--video-rate: the calibration files give no footage rate; give it in Hz")
    first = args.first_mocap_frame if args.first_mocap_frame is not None else first
    scheduler = "synchronous" if args.scheduler is None else (None if args.scheduler == "local" else args.scheduler)
    done = capture_wrinkles(args.result, cameras, args.video, args.masks, args.out, video_rate_hz=rate,
                            first_mocap_frame=first, depth_scale=args.depth_scale, scheduler=scheduler,
                            n_workers=args.workers, work_dir=args.work, exports=parse_export_formats(args.export),
                            anchor=not args.per_frame_projection, edits=edits,
                            min_face_in_view=args.min_face_in_view, progress=not args.quiet,
                            export_options={"export_frame": args.export_frame}, overwrite=args.overwrite)
    if not args.quiet:
        t = done.timings
        print(f"wrote {done.out_dir}: wrinkles on {done.n_video_frames} video frames (tracking {t['tracking_s']:.1f} s, "
              f"cross-sections and synthesis {t['cross_sections_and_synthesis_s']:.1f} s)")
    return 0


def _add_detail(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "detail",
        help="add fine detail from footage by space-time shape from shading (Lo et al.) to a result",
        description="Shade the layer below (an animate, blend, solve-muscles or wrinkles result) with the stage's "
        "calibrated lights, and solve the heights along its normals that make every camera's footage match, "
        "over windows of video frames on the frame runner; writes a result folder like the layer's plus "
        "detail.json.",
    )
    p.add_argument("--result", required=True,
                   help="the layer below: an animate, blend, solve-muscles or wrinkles result folder")
    p.add_argument("--cameras", required=True, nargs="+",
                   help="the facecap camera file (cameras.json), or one OpenCV calibration YAML per camera in --video order")
    p.add_argument("--video", required=True, nargs="+", help="one image folder or video file per camera")
    p.add_argument("--lights", required=True, help="the stage's lights, lights.json (docs/cameras.md, Lights)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--video-rate", type=float, default=None, help="footage rate in Hz [the camera file's]")
    p.add_argument("--first-mocap-frame", type=float, default=None,
                   help="mocap frame of video frame 0 [the camera file's, else 0]")
    p.add_argument("--regions", default=None,
                   help="restrict the detail to these vertices: a JSON list of indices or a .npy bool mask "
                        "[the face every camera sees well and a light reaches]")
    p.add_argument("--transfer", choices=("auto", "linear", "srgb"), default="auto",
                   help="how the footage encodes light [auto: 8-bit files sRGB, 16-bit and float linear]")
    p.add_argument("--uniform-albedo", action="store_true",
                   help="one albedo for the region, as the paper does, instead of one per sample from the rest frame")
    p.add_argument("--map-size", type=int, default=1024,
                   help="displacement (EXR) and normal (16-bit PNG) maps on the scan's UVs, texels a side; 0: none [1024]")
    p.add_argument("--bilateral", type=float, nargs="?", const=0.3, default=None, metavar="MM",
                   help="the paper's post-filter: an adaptive bilateral filter on the heights over the skin, with "
                        "this spatial standard deviation [off; MM 0.3 when given alone]")
    p.add_argument("--camera-units", default="mm", help="unit of T in OpenCV calibration files [mm]")
    p.add_argument("--scheduler", default=None,
                   help="Dask scheduler address for an existing cluster; 'local' for a local cluster of --workers "
                        "processes [run in this process]")
    p.add_argument("--workers", type=int, default=2, help="processes of a local cluster [2]")
    p.add_argument("--work", default=None, help="resumable work folder (kept; a rerun resumes) [a temporary one]")
    p.add_argument("--export", default="", help="exports, comma-separated, as for animate")
    _add_export_frame(p)
    _add_overwrite(p)
    p.set_defaults(func=_cmd_detail)


def _cmd_detail(args: argparse.Namespace) -> int:
    from .cameras import read_footage_cameras, read_light_file
    from .io.result_layout import parse_export_formats
    from .pipelines import capture_detail

    if args.workers < 1 or args.map_size < 0:
        raise FacecapError("--workers must be >= 1 and --map-size >= 0")
    lights = read_light_file(args.lights)  # before any long work
    cameras, rate, first = read_footage_cameras(args.cameras, args.video, unit=args.camera_units)
    rate = args.video_rate if args.video_rate is not None else rate
    if rate is None:
        raise FacecapError("--video-rate: the calibration files give no footage rate; give it in Hz")
    first = args.first_mocap_frame if args.first_mocap_frame is not None else first
    scheduler = "synchronous" if args.scheduler is None else (None if args.scheduler == "local" else args.scheduler)
    done = capture_detail(args.result, cameras, args.video, lights, args.out, video_rate_hz=rate,
                          first_mocap_frame=first, regions=args.regions, transfer=args.transfer,
                          per_sample_albedo=not args.uniform_albedo, map_size=args.map_size,
                          bilateral_mm=args.bilateral, scheduler=scheduler, n_workers=args.workers,
                          work_dir=args.work, exports=parse_export_formats(args.export), progress=not args.quiet,
                          export_options={"export_frame": args.export_frame}, overwrite=args.overwrite)
    if not args.quiet:
        t = done.timings
        print(f"wrote {done.out_dir}: detail on {done.n_video_frames} video frames over {done.region_vertices} "
              f"vertices (shape from shading {t['shape_from_shading_s']:.1f} s)")
def _add_calibrate_light(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "calibrate-light",
        help="a light's position (or direction) from footage of a chrome sphere seen by calibrated cameras",
        description="Find a chrome sphere of known radius and the light's highlight on it in each camera's "
        "footage (every frame one sphere position), fit the sphere, reflect each highlight's ray off it and "
        "meet the reflected rays: a point light, or a directional one when they are nearly parallel. "
        "Writes lights.json and a check picture beside it (docs/cameras.md, Lights).",
    )
    p.add_argument("--cameras", required=True, nargs="+",
                   help="the facecap camera file (cameras.json), or one OpenCV calibration YAML per camera in --images order")
    p.add_argument("--images", required=True, nargs="+",
                   help="one image, image folder or video per camera; frame f of each shows the same sphere position")
    p.add_argument("--sphere-radius", required=True, type=float, metavar="MM",
                   help="the sphere's radius in mm (half its diameter)")
    p.add_argument("--out", required=True, help="lights.json to write (its check picture goes beside it)")
    p.add_argument("--intensity", type=float, default=1.0, help="the light's relative intensity, written as given [1]")
    p.add_argument("--ambient", type=float, default=0.0, help="the room's relative ambient light, written as given [0]")
    p.add_argument("--kind", choices=("auto", "point", "directional"), default="auto",
                   help="auto: directional when the reflected rays are too near parallel for a distance [auto]")
    p.add_argument("--highlight-sigma", type=float, default=0.5, metavar="PX",
                   help="the highlight's assumed error in px, for the uncertainty [0.5]")
    p.add_argument("--camera-units", default="mm", help="unit of T in OpenCV calibration files [mm]")
    _add_overwrite(p, "an existing --out")
    p.set_defaults(func=_cmd_calibrate_light)


def _cmd_calibrate_light(args: argparse.Namespace) -> int:
    import numpy as np

    from .cameras import read_footage_cameras
    from .pipelines import calibrate_stage_light, light_check_path

    if not args.sphere_radius > 0 or not np.isfinite(args.sphere_radius):
        raise FacecapError(f"--sphere-radius: expected a positive radius in mm, got {args.sphere_radius}")
    if not args.highlight_sigma > 0 or not args.intensity >= 0 or not args.ambient >= 0:
        raise FacecapError("--highlight-sigma must be > 0, --intensity and --ambient >= 0")
    cameras = read_footage_cameras(args.cameras, args.images, unit=args.camera_units).cameras
    done = calibrate_stage_light(cameras, args.images, args.sphere_radius, args.out, intensity=args.intensity,
                                 ambient=args.ambient, kind=args.kind, highlight_sigma_px=args.highlight_sigma,
                                 overwrite=args.overwrite)
    if not args.quiet:
        light = done.light
        n_frames = done.sphere_centres.shape[0]
        if light.kind == "point":
            where = "point light at ({:.1f}, {:.1f}, {:.1f}) mm".format(*light.position)
            spread = f"sigma {done.sigma_mm[0]:.1f} / {done.sigma_mm[1]:.1f} / {done.sigma_mm[2]:.1f} mm"
            residual = "ray distances"
            unit = "mm"
        else:
            where = "directional light travelling ({:.4f}, {:.4f}, {:.4f})".format(*light.direction)
            spread = f"sigma {done.direction_sigma_deg:.2f} deg"
            residual = "ray angles x 1 m"
            unit = "mm"
        print(f"wrote {args.out}: {where} from {len(done.ray_distances_mm)} reflected rays "
              f"({len(cameras)} camera{'s' * (len(cameras) != 1)}, {n_frames} sphere position{'s' * (n_frames != 1)})")
        print(f"  {residual}: rms {float(np.sqrt(np.mean(done.ray_distances_mm ** 2))):.2f} {unit}, max "
              f"{float(done.ray_distances_mm.max()):.2f} {unit}; rays spread {done.spread_deg:.2f} deg; {spread}; "
              f"sphere outline rms {float(np.sqrt(np.mean(done.edge_rms_px ** 2))):.2f} px")
        print(f"  check picture: {light_check_path(args.out)}")
    return 0


def _add_remove_wrinkles(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("remove-wrinkles",
                       help="smooth the wrinkles out of a neutral scan in a region, keeping its fine detail "
                            "(Bickel et al. 2007, 5.4)")
    p.add_argument("--scan", required=True, help=f"the neutral scan: {_formats_read('mesh')}")
    p.add_argument("--scan-units", default="mm", help="length unit of the scan file [mm]")
    p.add_argument("--region", required=True,
                   help="the wrinkle region: a JSON list of vertex indices, or a .npy bool mask per vertex")
    p.add_argument("--out", required=True, help="the scan without its wrinkles (.obj or .ply)")
    _add_overwrite(p, "an existing file --out")
    p.set_defaults(func=_cmd_remove_wrinkles)


def _cmd_remove_wrinkles(args: argparse.Namespace) -> int:
    from .pipelines.remove_scan_wrinkles import remove_scan_wrinkles

    region = remove_scan_wrinkles(args.scan, args.region, args.out, scan_unit=args.scan_units,
                                  overwrite=args.overwrite)
    if not args.quiet:
        print(f"wrote {args.out}: {int(region.sum())} of {region.size} vertices smoothed")
    return 0


def _add_build_anatomy(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("build-anatomy",
                       help="bone, a tetrahedral soft-tissue mesh and 36 muscles inside a scan (Sifakis et al. 2005)")
    p.add_argument("--scan", required=True, help=f"the neutral scan: {_formats_read('mesh')}")
    p.add_argument("--scan-units", default="mm", help="length unit of the scan file [mm]")
    p.add_argument("--out", required=True, help="model folder (anatomy.npz, anatomy.json, layout.png)")
    p.add_argument("--landmarks", default=None,
                   help="JSON landmarks (name -> vertex index or point); not needed for scans in the ICT topology")
    p.add_argument("--tets", type=int, default=100_000, help="tetrahedra to aim for [100000]")
    _add_overwrite(p, "an earlier model in --out")
    p.set_defaults(func=_cmd_build_anatomy)


def _cmd_build_anatomy(args: argparse.Namespace) -> int:
    from .pipelines.build_anatomy_model import build_anatomy_model

    anatomy = build_anatomy_model(args.scan, args.out, scan_unit=args.scan_units, landmarks=args.landmarks,
                                  n_tets=args.tets, progress=not args.quiet, overwrite=args.overwrite)
    if not args.quiet:
        print(f"wrote {args.out}: {len(anatomy.tets)} tetrahedra, {len(anatomy.muscle_names)} muscles")
    return 0


def _add_solve_muscles(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "solve-muscles",
        help="muscle activations, cranium and jaw from a mocap take on an anatomy model (Sifakis et al. 2005)",
        description="Solve every frame of a take for the muscle activations and the cranium and jaw frames whose "
        "quasistatic face puts its markers where the take's are, on the frame runner (resumable chunks, each "
        "chunk's first frame from rest); writes a result folder like animate's plus activations.csv, "
        "bone_transforms.npz and activations.png.",
    )
    p.add_argument("--model", required=True, help="anatomy model folder (facecap build-anatomy)")
    p.add_argument("--markers", required=True, help=f"mocap take: {_formats_read('take')}")
    p.add_argument("--marker-units", default=None, help="override the unit the marker file declares")
    p.add_argument("--map", required=True,
                   help=f"marker map, {_formats_read('map')}: marker label -> vertex index or 3D point of the model's scan")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--rest-frame", type=int, default=0, help="frame whose expression matches the scan [0]")
    p.add_argument("--frames", default=None, metavar="A:B", help="solve only take frames A <= frame < B [all]")
    p.add_argument("--marker-offset", type=float, default=1.5,
                   help="marker centre height above the skin, mm: places the rest frame on the scan [1.5]")
    p.add_argument("--rest-average", type=float, default=0.1,
                   help="Gaussian sigma, s, of the average round the rest frame that gives the rest markers, as for "
                        "animate; 0: the rest frame alone [0.1]")
    p.add_argument("--retarget", choices=("auto", "rigid", "warp"), default="auto",
                   help="how the take reaches the scan: 'rigid' (a take of the scanned actor: the rest frame moved "
                        "rigidly, the cranium solves the head), 'warp' (animate's triharmonic warp: another face, or "
                        "a loose map), 'auto' (rigid when the rest frame fits within 5 mm, else the warp) [auto]")
    p.add_argument("--stabilize", default=None,
                   help="remove rigid head motion before the warp, as for animate: 'off', 'auto', 'consensus' or "
                        "labels [with the warp auto, rigid off]")
    p.add_argument("--no-smooth", action="store_true", help="skip the spatio-temporal bilateral filter")
    p.add_argument("--temporal-sigma", default="auto", type=_temporal_sigma,
                   help="the filter's temporal sigma in s, or 'auto': chosen for the take by cross-validation [auto]")
    p.add_argument("--scheduler", default="local",
                   help="'local' (a local Dask cluster of --workers processes), 'synchronous' (this process) or "
                        "the address of a Dask scheduler, tcp://HOST:PORT [local]")
    p.add_argument("--workers", type=int, default=2, help="processes of a local cluster [2]")
    p.add_argument("--work", default=None, help="resumable work folder (kept; a rerun resumes) [a temporary one]")
    p.add_argument("--chunk-frames", type=int, default=32,
                   help="frames per runner chunk; each chunk's first frame is solved from rest [32]")
    p.add_argument("--max-warm-steps", type=int, default=None,
                   help="Gauss-Newton steps of a frame warm-started from the one before [the solver's, 2]")
    p.add_argument("--marker-noise", type=float, default=None,
                   help="expected marker noise, mm (the penalty's starting weight) [the solver's, 0.2]")
    p.add_argument("--export", default="", help="exports, comma-separated, as for animate")
    _add_export_frame(p)
    _add_overwrite(p)
    p.set_defaults(func=_cmd_solve_muscles)


def _cmd_solve_muscles(args: argparse.Namespace) -> int:
    from pathlib import Path

    from .io.atomic_write import recorded_path
    from .io.result_layout import parse_export_formats
    from .io.read_markers import read_markers
    from .io.write_performance import check_result_destination
    from .pipelines import solve_muscle_take

    if args.workers < 1 or args.chunk_frames < 1:
        raise FacecapError("--workers and --chunk-frames: expected positive integers")
    exports = parse_export_formats(args.export)  # before any long work
    check_result_destination(args.out, overwrite=args.overwrite)
    model = Path(args.model)
    if not model.is_dir():
        raise FacecapError("no such model folder (make one with facecap build-anatomy)", path=str(model))
    take = read_markers(args.markers, unit=args.marker_units)
    options = {}
    if args.max_warm_steps is not None:
        options["max_warm_steps"] = args.max_warm_steps
    if args.marker_noise is not None:
        options["marker_noise_mm"] = args.marker_noise
    scheduler = {"local": None}.get(args.scheduler, args.scheduler)
    done = solve_muscle_take(model, take, args.map, args.out, rest_frame=args.rest_frame,
                             marker_offset_mm=args.marker_offset, retarget=args.retarget,
                             rest_average_s=args.rest_average,
                             stabilize=None if args.stabilize is None else _stabilize_option(args.stabilize),
                             smooth=not args.no_smooth,
                             temporal_sigma_s=args.temporal_sigma, frames=args.frames, scheduler=scheduler,
                             n_workers=args.workers, work_dir=args.work, chunk_frames=args.chunk_frames,
                             exports=exports, solver_options=options, progress=not args.quiet,
                             extra_metadata={"map": recorded_path(args.map, folder=args.out)},
                             export_options={"export_frame": args.export_frame}, overwrite=args.overwrite)
    if not args.quiet:
        r = done.report
        t = r["timings"]
        rms = r["marker_residual_mm"]["rms"]
        print(f"wrote {done.out_dir}: {done.n_frames} frames x {r['n_muscles']} muscles from "
              f"{r['n_markers']} markers, marker rms {'-' if rms is None else f'{rms:.3f}'} mm, "
              f"{r['frames_flagged']} frames flagged (solve {t['solve_s']:.1f} s, "
              f"{len(done.computed)} chunks computed, {len(done.reused)} reused)")
    return 0


def _add_edit_muscles(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "edit-muscles",
        help="edit a solve-muscles result in muscle space: interpolate, exaggerate, press a sphere (Sifakis et al. 2005)",
        description="Re-solve the face of a solve-muscles result under edited controls (Sifakis et al. 2005, sec. 9): "
        "interpolate two frames in activation and bone space, exaggerate every frame by scaling the muscles' "
        "force-length curves, or press a kinematic sphere on every frame. Writes a result folder like "
        "solve-muscles'.",
    )
    p.add_argument("--result", required=True, help="a solve-muscles result folder")
    edit = p.add_mutually_exclusive_group(required=True)
    edit.add_argument("--scale-force-length", type=float, default=None, metavar="X",
                      help="re-solve every frame with the force-length curves scaled by X > 0 (activations unchanged)")
    edit.add_argument("--interpolate", type=int, nargs=2, default=None, metavar=("A", "B"),
                      help="frames A to B of the result (activations.csv's frame numbers), --frames frames")
    edit.add_argument("--sphere", type=float, nargs=4, default=None, metavar=("CX", "CY", "CZ", "R"),
                      help="a sphere, centre and radius in mm in the result's coordinates, pressing on every frame")
    p.add_argument("--sphere-to", type=float, nargs=3, default=None, metavar=("CX", "CY", "CZ"),
                   help="the sphere's centre at the last frame (it moves linearly) [it stays]")
    p.add_argument("--frames", type=int, default=None, help="frames of the interpolation, both ends included [30]")
    p.add_argument("--model", default=None, help="the anatomy model folder [the one performance.json names]")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--export", default="", help="exports, comma-separated, as for animate")
    _add_export_frame(p)
    _add_overwrite(p)
    p.set_defaults(func=_cmd_edit_muscles)


def _cmd_edit_muscles(args: argparse.Namespace) -> int:
    from .io.result_layout import parse_export_formats
    from .pipelines import edit_muscles

    exports = parse_export_formats(args.export)  # before any long work
    if args.sphere_to is not None and args.sphere is None:
        raise FacecapError("--sphere-to: only with --sphere")
    if args.interpolate is None and args.frames is not None:
        raise FacecapError("--frames: only with --interpolate")
    done = edit_muscles(args.result, args.out, scale_force_length=args.scale_force_length,
                        interpolate=None if args.interpolate is None else tuple(args.interpolate),
                        n_frames=30 if args.frames is None else args.frames, sphere=args.sphere, sphere_to=args.sphere_to, model_dir=args.model,
                        exports=exports, progress=not args.quiet, export_options={"export_frame": args.export_frame},
                        overwrite=args.overwrite)
    if not args.quiet:
        r = done.report
        line = (f"wrote {done.out_dir}: {done.n_frames} frames ({r['edit']['kind']}), "
                f"{len(r['not_converged_frames'])} not converged, solve {r['timings']['solve_s']:.1f} s")
        if "sphere" in r:
            line += (f", deepest penetration {r['sphere']['max_scan_penetration_mm']:.3f} mm (scan vertices), "
                     f"{r['sphere']['max_skin_node_penetration_mm']:.3f} mm (skin nodes)")
        print(line)
    return 0


def _add_demo(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="run the main job on the bundled sample, writing facecap-demo/")
    p.add_argument("--out", default="facecap-demo", help="output folder [facecap-demo]")
    p.add_argument("--frames", type=int, default=300, help="frames of the generated take [300]")
    _add_overwrite(p, "an earlier demo in --out (a second run needs it)")
    p.set_defaults(func=_cmd_demo)


def _cmd_demo(args: argparse.Namespace) -> int:
    from .pipelines.run_demo import run_demo

    summary = run_demo(args.out, n_frames=args.frames, progress=not args.quiet, overwrite=args.overwrite)
    if not args.quiet:
        for line in summary:
            print(line)
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``facecap`` command."""
    parser = argparse.ArgumentParser(
        prog="facecap",
        description="Facial performance capture: animate a face scan from a facial mocap take.",
    )
    parser.add_argument("--version", action="version", version=f"facecap {__version__}")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bars or notices")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_animate(sub)
    _add_info(sub)
    _add_map(sub)
    _add_evaluate(sub)
    _add_export(sub)
    _add_view(sub)
    _add_scan_commands(sub)
    _add_synth(sub)
    _add_wrinkles(sub)
    _add_detail(sub)
    _add_remove_wrinkles(sub)
    _add_calibrate_light(sub)
    _add_build_anatomy(sub)
    _add_solve_muscles(sub)
    _add_edit_muscles(sub)
    _add_demo(sub)
    for action in sub.choices.values():  # let -q/--quiet also follow the command
        action.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
                            help="no progress bars or notices")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``facecap`` console script; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not hasattr(args, "quiet"):
        args.quiet = False

    def show_warning(message, category, filename, lineno, file=None, line=None):  # noqa: ANN001
        if not args.quiet:
            print(f"facecap: note: {message}", file=sys.stderr)

    with warnings.catch_warnings():
        warnings.simplefilter("always", FacecapWarning)
        warnings.showwarning = show_warning  # one line per notice, no source echo
        try:
            return int(args.func(args) or 0)
        except FacecapError as exc:
            print(f"facecap: error: {exc}", file=sys.stderr)
            return EXIT_BAD_INPUT
        except FileNotFoundError as exc:
            print(f"facecap: error: {exc.filename}: no such file", file=sys.stderr)
            return EXIT_BAD_INPUT
        except IsADirectoryError as exc:
            print(f"facecap: error: {exc.filename}: is a folder, expected a file", file=sys.stderr)
            return EXIT_BAD_INPUT
        except PermissionError as exc:
            print(f"facecap: error: {exc.filename}: permission denied", file=sys.stderr)
            return EXIT_BAD_INPUT
        except KeyboardInterrupt:
            print("facecap: interrupted; nothing was written to the output folder", file=sys.stderr)
            return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
