"""The compact result against today's full write: time and size of ``animate`` end to end (issue 12).

One run, one process, the same inputs as ``bench_thin_shell.py`` (the ICT face upsampled, 90
farthest-point markers, smooth marker motion at 120 Hz):

1. **compact**: ``animate_scan(..., write_vertices=False, exports=['usd'])``: the rig and the USD
   blend shapes, no ``vertices.npy``; wall time end to end against the set-up alone (the shell's
   factorisation and basis and the marker offsets, what ``timings.shell_setup_s`` covers, built by
   themselves in the same process, once before and once after each of ``--repeats`` runs, the faster
   of a run's two taken, the median of the runs' ratios reported: inside
   ``animate`` the mesh check runs on a second thread beside it, so the run's own
   ``shell_setup_s`` is not the set-up alone), and the bytes written;
2. **glTF review file** of that result (``export_result(..., 'gltf')``): the review mesh, the
   principal components, the GLB; wall time;
3. **today's full write** (``vertices.npy``, no rig consumer) on ``--baseline-frames`` frames of the
   same take (the disk cannot hold 86 GB here), scaled linearly to the take's length: the write
   streams at a constant rate (``bench_thin_shell.py``: first and last quarter equal).

Prints one JSON object; ``--markdown`` also prints the RESULTS.md table rows.

    python benchmarks/bench_compact_output.py --case 700k --frames 10000 --baseline-frames 1000
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np


sys.path.insert(0, str(Path(__file__).resolve().parent))
import _meshes  # noqa: E402
from bench_thin_shell import N_MARKERS, RATE_HZ, machine_facts  # noqa: E402


def _folder_bytes(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())


def _case(case: str, frames: int, work: Path) -> tuple[Any, Any, Any]:
    from facecap.io import read_correspondence
    from facecap.structures import MarkerSequence, Mesh

    mesh = _meshes.bench_mesh(case)
    marker_vertices = _meshes.farthest_point_markers(mesh.V, N_MARKERS)
    motion = _meshes.smooth_marker_motion(frames, N_MARKERS, rate_hz=RATE_HZ, seed=0)
    labels = tuple(f"M{k:03d}" for k in range(N_MARKERS))
    positions = mesh.V[marker_vertices][None] + motion
    scan = Mesh(mesh.V, mesh.F, source_unit="mm", source_path=f"bench:{len(mesh.V)}")
    map_path = work / "map.json"
    map_path.write_text(json.dumps({s: int(v) for s, v in zip(labels, marker_vertices)}))
    take = MarkerSequence(positions, labels, rate=RATE_HZ)
    return scan, take, read_correspondence(map_path, scan)


def _setup_alone(scan: Any, take: Any, corr: Any) -> float:
    """Seconds to build what ``animate``'s ``shell_setup_s`` covers, nothing else running."""
    from facecap.deform import MarkerOffsets, ThinShellSolver
    from facecap.markers import prepare_markers

    vertices = prepare_markers(take, scan, corr).constrained_vertices
    t = time.perf_counter()
    solver = ThinShellSolver(scan.vertices, scan.faces, vertices)
    MarkerOffsets(scan.vertices, scan.faces, solver)
    return time.perf_counter() - t


def _animate(scan: Any, take: Any, corr: Any, out: Path, **kwargs: Any) -> tuple[float, dict[str, Any]]:
    from facecap.pipelines import animate_scan

    t = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = animate_scan(scan, take, corr, out, progress=False, **kwargs)
    return time.perf_counter() - t, result.report


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--case", choices=_meshes.CASES, default="100k")
    p.add_argument("--frames", type=int, default=10_000)
    p.add_argument("--baseline-frames", type=int, default=1000)
    p.add_argument("--work", default=str(Path(__file__).resolve().parent / "_work" / "compact"))
    p.add_argument("--no-gltf", action="store_true")
    p.add_argument("--repeats", type=int, default=3,
                   help="compact runs, each between two set-ups alone; the ratio is their median [3]")
    p.add_argument("--markdown", action="store_true")
    args = p.parse_args(argv)

    from facecap.io import read_result
    from facecap.pipelines import export_result

    work = Path(args.work)
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    scan, take, corr = _case(args.case, args.frames, work)
    out: dict[str, Any] = {"case": args.case, "vertices": scan.n_vertices, "markers": N_MARKERS,
                           "frames": args.frames, "machine": machine_facts()}

    # set-up alone, then each run followed by a set-up alone: every run has one just before and one just after it
    # (this machine's speed drifts by 1.5x within the hour; a run is compared only with the set-ups beside it)
    setups = [_setup_alone(scan, take, corr)]
    walls = []
    for _ in range(max(1, args.repeats)):
        shutil.rmtree(work / "compact", ignore_errors=True)
        wall, report = _animate(scan, take, corr, work / "compact", write_vertices=False, exports=["usd"])
        walls.append(wall)
        setups.append(_setup_alone(scan, take, corr))
    conservative = [w / min(a, b) for w, a, b in zip(walls, setups, setups[1:])]  # the faster set-up beside it
    against_mean = [w / (0.5 * (a + b)) for w, a, b in zip(walls, setups, setups[1:])]
    compact_bytes = _folder_bytes(work / "compact")
    info = read_result(work / "compact").info
    out["compact"] = {
        "wall_s": float(np.median(walls)), "walls_s": walls, "setup_alone_runs_s": setups,
        "setup_s": float(np.median(setups)), "setup_in_run_s": report["timings"]["shell_setup_s"],
        "ratio_to_setup": float(np.median(conservative)), "ratios_to_setup": conservative,
        "ratio_to_mean_setup": float(np.median(against_mean)), "ratios_to_mean_setup": against_mean,
        "timings": report["timings"], "bytes": compact_bytes,
        "files": info["files"], "usd": info.get("exports_report", {}).get("usd"),
    }

    if not args.no_gltf:
        t = time.perf_counter()
        gltf = export_result(work / "compact", "gltf", out_dir=work / "review")
        out["gltf"] = {"wall_s": time.perf_counter() - t, **gltf["gltf"]}

    short = take.select(take.labels) if args.baseline_frames >= args.frames else _first_frames(take, args.baseline_frames)
    wall_full, report_full = _animate(scan, short, corr, work / "full")
    full_bytes = (work / "full" / "vertices.npy").stat().st_size
    scale = args.frames / short.n_frames
    out["full_write"] = {
        "frames": short.n_frames, "wall_s": wall_full, "setup_s": report_full["timings"]["shell_setup_s"],
        "write_s": report_full["timings"]["deform_and_write_s"], "vertices_npy_bytes": full_bytes,
        "scaled_to_take": {"write_s": report_full["timings"]["deform_and_write_s"] * scale,
                           "vertices_npy_bytes": full_bytes * scale,
                           "wall_s": wall_full - report_full["timings"]["deform_and_write_s"]
                           + report_full["timings"]["deform_and_write_s"] * scale},
    }
    out["size_ratio"] = compact_bytes / out["full_write"]["scaled_to_take"]["vertices_npy_bytes"]
    print(json.dumps(out, indent=1, default=str))
    if args.markdown:
        c, f = out["compact"], out["full_write"]["scaled_to_take"]
        print(f"| compact (rig + USD blend shapes) | {c['wall_s']:.1f} s ({c['ratio_to_setup']:.2f}x set-up "
              f"{c['setup_s']:.1f} s) | {compact_bytes / 1e9:.3f} GB (1/{1 / out['size_ratio']:.0f}) |")
        print(f"| today's full write (scaled from {short.n_frames}) | {f['wall_s']:.1f} s | "
              f"{f['vertices_npy_bytes'] / 1e9:.1f} GB |")
        if "gltf" in out:
            print(f"| glTF review file | {out['gltf']['wall_s']:.1f} s | {sum(out['gltf']['files'].values()) / 1e6:.0f} MB |")
    shutil.rmtree(work / "full", ignore_errors=True)


def _first_frames(take: Any, n: int) -> Any:
    from facecap.structures import MarkerSequence

    return MarkerSequence(take.positions[:n], take.labels, rate=take.rate)


if __name__ == "__main__":
    main()
