"""Speed and memory of the large-scale step (Bickel et al. 2007, sec. 4.2): thin-shell set-up and per-frame deformation.

One configuration per run, in a fresh process, printing one ``RESULT {json}`` line::

    python benchmarks/bench_thin_shell.py --case 700k --mode speed --frames 1000
    python benchmarks/bench_thin_shell.py --case 700k --mode stream --frames 10000 --sink null
    python benchmarks/bench_thin_shell.py --case 100k --mode setup --backend scipy

or the whole set, each configuration in its own subprocess, ending with markdown tables::

    python benchmarks/bench_thin_shell.py --all [--save results.json]

Modes
-----
speed
    ``ThinShellSolver(..., keep_factor=True)`` once, then, ``--repeats`` times:
    batched ``deform_into`` over all frames (compute only, preallocated output,
    batch 16/32/64), the same with the int16 product (``precision='int16'``),
    and the bare GEMM into a preallocated (3b, n) array (no layout change: a
    reference, not the product users get); ``solve_direct`` (sparse back-substitution with the kept
    factor) on ``--direct-frames`` frames, the ratio taken against the batch-32
    run of the same repeat; and the streamed loop of ``animate_scan`` (same
    code: two buffers, one writer thread, ``PerformanceWriter``) writing a real
    ``vertices.npy``. Outputs are deleted after each repeat.
stream
    The real :func:`facecap.pipelines.animate_scan.animate_scan` on a synthetic
    take (markers at their vertices plus the smooth motion, vertex-index
    correspondence), then ``ru_maxrss`` of the process: the peak memory of a
    whole take. ``--sink null`` opens ``vertices.npy`` on ``/dev/null`` (every
    byte still goes through ``write``), for takes too large for the disk.
setup
    Only the solver construction: time and ``ru_maxrss`` (for backends).

Every figure comes with the CPU time that other processes took while it was
measured (``other_cores``: busy CPU time of the machine from ``/proc/stat`` minus
this process's own, per second of wall time), since this 2-core machine is shared.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _meshes  # noqa: E402
from _load import Window, peak_rss_gb  # noqa: E402

N_MARKERS = 90
RATE_HZ = 60.0
GB = 1e9


# --------------------------------------------------------------------------- measuring


def _vm_kb(field: str) -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    return 0


class MemoryProbe:
    """Split a run's peak memory at the end of the solver set-up, and sample RSS while streaming.

    Replaces ``ThinShellSolver`` inside ``animate_scan`` by a subclass that, once
    constructed, records ``ru_maxrss`` (the peak so far: inputs, checks, set-up),
    resets the kernel's high-water mark (``/proc/self/clear_refs`` = 5, which
    ``ru_maxrss`` reads) and starts sampling ``VmRSS`` every 0.2 s.
    """

    def __init__(self) -> None:
        self.setup_peak_gb = float("nan")
        self.samples: list[tuple[float, float]] = []
        self._stop = False
        self._thread: Any = None

    def install(self) -> None:
        import importlib
        import threading

        module = importlib.import_module("facecap.pipelines.animate_scan")  # the module, not the function

        probe, base = self, module.ThinShellSolver

        class _Probed(base):  # type: ignore[misc, valid-type]
            def __init__(self, *a: Any, **k: Any) -> None:
                super().__init__(*a, **k)
                probe.setup_peak_gb = peak_rss_gb()
                with open("/proc/self/clear_refs", "w") as f:
                    f.write("5")
                probe._thread = threading.Thread(target=probe._sample, daemon=True)
                probe._thread.start()

        module.ThinShellSolver = _Probed

    def _sample(self) -> None:
        t0 = time.perf_counter()
        while not self._stop:
            self.samples.append((time.perf_counter() - t0, _vm_kb("VmRSS") * 1024 / GB))
            time.sleep(0.2)

    def stop(self) -> dict[str, float]:
        self._stop = True
        if self._thread is not None:
            self._thread.join()
        after = peak_rss_gb()
        rss = [r for _, r in self.samples]
        q = max(1, len(rss) // 4)
        return {
            "peak_rss_gb": max(self.setup_peak_gb, after),
            "peak_rss_setup_gb": self.setup_peak_gb,
            "peak_rss_after_setup_gb": after,
            "rss_stream_first_quarter_max_gb": max(rss[:q]) if rss else float("nan"),
            "rss_stream_last_quarter_max_gb": max(rss[-q:]) if rss else float("nan"),
            "rss_samples": len(rss),
        }


def _median(xs: list[float]) -> float:
    return float(statistics.median(xs))


# --------------------------------------------------------------------------- inputs


def _inputs(case: str, frames: int) -> tuple[_meshes.BenchMesh, np.ndarray, np.ndarray]:
    mesh = _meshes.bench_mesh(case)
    markers = _meshes.farthest_point_markers(mesh.V, N_MARKERS)
    motion = _meshes.smooth_marker_motion(frames, N_MARKERS, rate_hz=RATE_HZ, seed=0)
    return mesh, markers, motion


def _build_solver(mesh: _meshes.BenchMesh, markers: np.ndarray, **kw: Any) -> tuple[Any, Window]:
    from facecap.deform.thin_shell import ThinShellSolver

    with Window() as w:
        solver = ThinShellSolver(mesh.V, mesh.F, markers, **kw)
    return solver, w


# --------------------------------------------------------------------------- the streamed loop


def stream_frames(solver: Any, writer: Any, disp32: np.ndarray, rest32: np.ndarray, batch: int) -> None:
    """The deform-and-write loop of ``animate_scan``: the same ``PerformanceWriter.stream`` call."""
    writer.stream(lambda start, stop, out: solver.deform_into(disp32[start:stop], rest32, out), batch_frames=batch)


def _scan(mesh: _meshes.BenchMesh) -> Any:
    from facecap.structures import Mesh

    return Mesh(mesh.V, mesh.F, source_unit="mm", source_path=f"bench:{len(mesh.V)}")


def _null_sink() -> None:
    """Make PerformanceWriter open vertices.npy on /dev/null (the bytes still go through write())."""
    from facecap.io import write_performance

    base = write_performance._NpyStream

    class _NullNpyStream(base):  # type: ignore[misc, valid-type]
        def __init__(self, path: Path, shape: tuple[int, ...], dtype: np.dtype) -> None:
            super().__init__(Path(os.devnull), shape, dtype)

    write_performance._NpyStream = _NullNpyStream


# --------------------------------------------------------------------------- modes


def run_speed(args: argparse.Namespace) -> dict[str, Any]:
    from facecap.deform.basis_product import BasisProduct
    from facecap.io.write_performance import PerformanceWriter
    from facecap.pipelines.finish_result import finish_result

    mesh, markers, motion = _inputs(args.case, args.frames)
    solver, w_setup = _build_solver(mesh, markers, keep_factor=True)
    n, T = len(mesh.V), args.frames
    disp32 = motion.astype(np.float32)
    rest32 = mesh.V.astype(np.float32)
    batches = [int(b) for b in args.batches.split(",")]
    out_root = Path(tempfile.mkdtemp(prefix="facecap-bench-", dir=args.out_dir))
    scan = _scan(mesh)

    # accuracy sanity: the dense basis against the sparse solve, one frame
    ref = solver.solve_direct(motion[T // 2])
    fast = solver.displacements(disp32[T // 2]).astype(np.float64)
    max_err_mm = float(np.abs(ref - fast).max())

    compute: dict[int, list[dict[str, float]]] = {b: [] for b in batches}
    int16: dict[int, list[dict[str, float]]] = {b: [] for b in batches}
    gemm_only: dict[int, list[dict[str, float]]] = {b: [] for b in batches}
    out = np.empty((batches[0], n, 3), np.float32)
    ref = solver.deform_into(disp32[: batches[0]], rest32, np.empty_like(out))
    basis = solver.basis  # (K, n) float32, for the bare GEMM
    fixed = None if args.no_int16 else BasisProduct(basis.T, precision="int16")
    int16_err_mm = (float("nan") if fixed is None
                    else float(np.abs(fixed.apply_into(disp32[: batches[0]], rest32, out) - ref).max()))
    del out, ref
    direct: list[dict[str, float]] = []
    ratios: list[float] = []
    e2e: list[dict[str, float]] = []
    per_rep_direct = max(1, round(args.direct_frames / args.repeats))
    for rep in range(args.repeats):
        for b in batches:
            out = np.empty((b, n, 3), np.float32)
            solver.deform_into(disp32[:b], rest32, out)  # warm the buffer's pages
            with Window() as w:
                for start in range(0, T, b):
                    stop = min(start + b, T)
                    solver.deform_into(disp32[start:stop], rest32, out[: stop - start])
            compute[b].append({"fps": T / w.seconds, "other_cores": w.other_cores, "my_cores": w.my_cores})
            if fixed is not None:
                with Window() as w:
                    for start in range(0, T, b):
                        stop = min(start + b, T)
                        fixed.apply_into(disp32[start:stop], rest32, out[: stop - start])
                int16[b].append({"fps": T / w.seconds, "other_cores": w.other_cores, "my_cores": w.my_cores})
            # the floor: the product alone into a preallocated (3b, n) array, no layout change, no rest
            scratch = np.empty((3 * b, n), np.float32)
            with Window() as w:
                for start in range(0, T, b):
                    stop = min(start + b, T)
                    X = np.ascontiguousarray(disp32[start:stop].transpose(2, 0, 1).reshape(3 * (stop - start), -1))
                    np.matmul(X, basis, out=scratch[: 3 * (stop - start)])
            gemm_only[b].append({"fps": T / w.seconds, "other_cores": w.other_cores, "my_cores": w.my_cores})
            del out, scratch
        frames = range(rep * per_rep_direct, (rep + 1) * per_rep_direct)
        with Window() as w:
            for t in frames:
                solver.solve_direct(motion[t])
        s_per_frame = w.seconds / per_rep_direct
        direct.append({"s_per_frame": s_per_frame, "other_cores": w.other_cores})
        ref_b = 32 if 32 in batches else batches[0]
        ratios.append(compute[ref_b][-1]["fps"] * s_per_frame)
        if not args.no_write:
            dest = out_root / f"take{rep}"
            with Window() as w:
                with PerformanceWriter(dest, mesh=scan, rate=RATE_HZ, n_frames=T) as writer:
                    stream_frames(solver, writer, disp32, rest32, args.batch)
                    finish_result(writer, {"benchmark": True})
            with Window() as w_sync:
                os.sync()
            size = (dest / "vertices.npy").stat().st_size
            e2e.append({
                "fps": T / w.seconds, "fps_incl_sync": T / (w.seconds + w_sync.seconds),
                "other_cores": w.other_cores, "write_gb": size / GB,
                "MBps": size / w.seconds / 1e6, "MBps_incl_sync": size / (w.seconds + w_sync.seconds) / 1e6,
            })
            shutil.rmtree(dest)
    shutil.rmtree(out_root, ignore_errors=True)
    res: dict[str, Any] = {
        "setup_s": w_setup.seconds, "setup_other_cores": w_setup.other_cores,
        "max_err_dense_vs_sparse_mm": max_err_mm,
        "compute": {str(b): v for b, v in compute.items()},
        "compute_fps_median": {str(b): _median([r["fps"] for r in v]) for b, v in compute.items()},
        "int16": {str(b): v for b, v in int16.items()},
        "int16_fps_median": {str(b): _median([r["fps"] for r in v]) for b, v in int16.items() if v},
        "int16_max_diff_mm": int16_err_mm,
        "gemm_only": {str(b): v for b, v in gemm_only.items()},
        "gemm_only_fps_median": {str(b): _median([r["fps"] for r in v]) for b, v in gemm_only.items()},
        "direct": direct, "direct_s_per_frame_median": _median([d["s_per_frame"] for d in direct]),
        "direct_frames_total": per_rep_direct * args.repeats,
        "speedup": ratios, "speedup_median": _median(ratios),
        "e2e": e2e,
    }
    if e2e:
        res["e2e_fps_median"] = _median([e["fps"] for e in e2e])
        res["e2e_fps_incl_sync_median"] = _median([e["fps_incl_sync"] for e in e2e])
    return res


def run_stream(args: argparse.Namespace) -> dict[str, Any]:
    import warnings

    from facecap.pipelines.animate_scan import animate_scan
    from facecap.structures import Correspondence
    from facecap.structures import MarkerSequence

    if args.sink == "null":
        _null_sink()
    mesh, markers, motion = _inputs(args.case, args.frames)
    labels = tuple(f"M{k:03d}" for k in range(N_MARKERS))
    take = MarkerSequence(mesh.V[markers][None] + motion, labels, RATE_HZ)
    corr = Correspondence(labels, np.repeat(markers[:, None], 3, axis=1), np.tile([1.0, 0.0, 0.0], (N_MARKERS, 1)))
    rss_inputs = peak_rss_gb()
    probe = MemoryProbe()
    probe.install()
    out_root = Path(tempfile.mkdtemp(prefix="facecap-bench-", dir=args.out_dir))
    dest = out_root / "take"
    with Window() as w, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = animate_scan(_scan(mesh), take, corr, dest, batch_frames=args.batch, progress=False)
    size = (dest / "vertices.npy").stat().st_size if (dest / "vertices.npy").exists() else 0
    mem = probe.stop()
    shutil.rmtree(out_root, ignore_errors=True)
    timings = result.report["timings"]
    return {
        "sink": args.sink, **mem, "peak_rss_inputs_gb": rss_inputs,
        "vertices_npy_gb": size / GB, "streamed_gb": args.frames * len(mesh.V) * 12 / GB,
        "wall_s": w.seconds, "other_cores": w.other_cores, "timings": timings,
        "setup_s": timings["shell_setup_s"], "e2e_fps": timings["frames_per_second"],
    }


def run_setup(args: argparse.Namespace) -> dict[str, Any]:
    mesh, markers, _ = _inputs(args.case, 1)
    rss0 = peak_rss_gb()
    solver, w = _build_solver(mesh, markers, backend=args.backend)
    return {"backend": solver.backend, "setup_s": w.seconds, "other_cores": w.other_cores,
            "peak_rss_gb": peak_rss_gb(), "peak_rss_inputs_gb": rss0}


def run_one(args: argparse.Namespace) -> dict[str, Any]:
    t0 = time.perf_counter()
    load0 = os.getloadavg()
    mesh = _meshes.bench_mesh(args.case)
    res = {"speed": run_speed, "stream": run_stream, "setup": run_setup}[args.mode](args)
    return {
        "case": args.case, "mode": args.mode, "frames": args.frames, "batch": args.batch,
        "n_vertices": len(mesh.V), "n_triangles": len(mesh.F), "mesh": mesh.description,
        "loadavg_start": load0, "loadavg_end": os.getloadavg(),
        "process_s": time.perf_counter() - t0, **res,
    }


# --------------------------------------------------------------------------- driver


def machine_facts() -> dict[str, Any]:
    import importlib.metadata as md

    facts: dict[str, Any] = {}
    with open("/proc/cpuinfo") as f:
        for line in f:
            if line.startswith("model name"):
                facts["cpu"] = line.split(":", 1)[1].strip()
                break
    with open("/proc/cpuinfo") as f:
        flags = next((ln.split(":", 1)[1].split() for ln in f if ln.startswith("flags")), [])
    facts["simd"] = " ".join(x for x in ("avx2", "fma", "avx512f") if x in flags)
    facts["cores"] = os.cpu_count()
    with open("/proc/meminfo") as f:
        facts["ram_gb"] = round(int(f.readline().split()[1]) * 1024 / GB, 1)
    cfg = np.show_config(mode="dicts")
    blas = cfg["Build Dependencies"]["blas"]
    facts["numpy"] = np.__version__
    facts["numpy_blas"] = f"{blas['name']} {blas.get('version', '')}".strip()
    for pkg in ("scipy", "pypardiso", "mkl", "libigl"):
        try:
            facts[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            facts[pkg] = "not installed"
    facts["python"] = sys.version.split()[0]
    facts["loadavg"] = os.getloadavg()
    return facts


def disk_speed(out_dir: str | None, gib: int = 4) -> dict[str, float]:
    """``dd`` write speed (MB/s, median of 3), into the page cache and with ``conv=fdatasync``."""
    folder = Path(tempfile.mkdtemp(prefix="facecap-dd-", dir=out_dir))
    res: dict[str, float] = {}
    try:
        for name, extra in (("dd_cached_MBps", []), ("dd_fdatasync_MBps", ["conv=fdatasync"])):
            speeds = []
            for _ in range(3):
                target = folder / "dd.bin"
                t = time.perf_counter()
                subprocess.run(["dd", "if=/dev/zero", f"of={target}", "bs=8M", f"count={128 * gib}", *extra],
                               check=True, capture_output=True)
                speeds.append(gib * 1024**3 / (time.perf_counter() - t) / 1e6)
                target.unlink()
                os.sync()
            res[name] = _median(speeds)
            res[name + "_all"] = speeds  # type: ignore[assignment]
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return res


CONFIGS: list[list[str]] = [
    ["--case", "100k", "--mode", "setup", "--backend", "pardiso"],
    ["--case", "100k", "--mode", "setup", "--backend", "scipy"],
    *[["--case", c, "--mode", "speed", "--frames", "1000"] for c in _meshes.CASES],
    *[["--case", c, "--mode", "stream", "--frames", "1000"] for c in _meshes.CASES],
    ["--case", "100k", "--mode", "stream", "--frames", "10000"],
    ["--case", "700k", "--mode", "stream", "--frames", "10000", "--sink", "null"],
]


def run_all(args: argparse.Namespace) -> list[dict[str, Any]]:
    facts = machine_facts()
    print("machine:", json.dumps(facts), flush=True)
    disk = disk_speed(args.out_dir)
    print("disk:", json.dumps(disk), flush=True)
    results = []
    for cfg in CONFIGS:
        if args.only and cfg[1] not in args.only.split(","):
            continue
        cmd = [sys.executable, __file__, *cfg, "--repeats", str(args.repeats)]
        if args.out_dir:
            cmd += ["--out-dir", args.out_dir]
        print("$", " ".join(cmd[1:]), flush=True)
        proc = subprocess.run(cmd, capture_output=True, text=True)
        line = next((ln for ln in reversed(proc.stdout.splitlines()) if ln.startswith("RESULT ")), None)
        if proc.returncode or line is None:
            print(proc.stdout[-2000:], proc.stderr[-4000:], flush=True)
            results.append({"config": cfg, "error": proc.stderr[-1000:]})
            continue
        r = json.loads(line[7:])
        print("  ", _short(r), flush=True)
        results.append(r)
    payload = {"machine": facts, "disk": disk, "results": results}
    if args.save:
        Path(args.save).write_text(json.dumps(payload, indent=1))
    print()
    print(markdown(payload))
    return results


def _short(r: dict[str, Any]) -> str:
    keys = ("setup_s", "compute_fps_median", "speedup_median", "e2e_fps_median", "e2e_fps", "peak_rss_gb", "process_s")
    return json.dumps({k: r[k] for k in keys if k in r})


def _pool(runs: list[dict[str, Any]], key: str, b: str, value: str, max_other: float) -> tuple[float, int]:
    xs = [x[value] for r in runs for x in r.get(key, {}).get(b, []) if x["other_cores"] <= max_other]
    return (_median(xs), len(xs)) if xs else (float("nan"), 0)


def markdown(payload: dict[str, Any], *, max_other: float = float("inf")) -> str:
    """The tables of RESULTS_thin_shell.md from saved results.

    Repeats of the same speed configuration (from one or several runs) are
    pooled; only those during which other processes used at most
    ``max_other`` cores count, and each cell says how many did (``n``).
    """
    m, disk, rs = payload["machine"], payload["disk"], [r for r in payload["results"] if "error" not in r]
    L = []
    L.append(f"Machine: {m['cpu']} ({m['simd']}), {m['cores']} cores, {m['ram_gb']} GB RAM; Python {m['python']}, "
             f"numpy {m['numpy']} ({m['numpy_blas']}), scipy {m['scipy']}, pypardiso {m['pypardiso']} "
             f"(MKL {m['mkl']}), libigl {m['libigl']}. Disk (dd, 4 GiB of 8 MiB blocks, median of 3): "
             f"{disk['dd_fdatasync_MBps']:.0f} MB/s with fdatasync, {disk['dd_cached_MBps']:.0f} MB/s into the page cache.")
    L.append("")
    if max_other != float("inf"):
        L.append(f"Speed figures: medians over the repeats during which other processes used <= {max_other} cores "
                 "(n = how many of them).")
        L.append("")
    L.append("| mesh | vertices | set-up s | fps, deform_into b=16 / 32 / 64 | fps, int16 product | "
             "fps, GEMM alone | solve_direct s/frame | speed-up (b=32) | end-to-end fps | incl. final sync |")
    L.append("|---|---|---|---|---|---|---|---|---|---|")
    for case in _meshes.CASES:
        runs = [r for r in rs if r["mode"] == "speed" and r["case"] == case]
        if not runs:
            continue
        setups = [r["setup_s"] for r in runs if r["setup_other_cores"] <= max_other]
        setups += [r["setup_s"] for r in rs if r["mode"] == "stream" and r["case"] == case
                   and r["other_cores"] <= max_other]
        # direct and e2e are lists of repeats; wrap them so _pool can read them
        wrapped = [{**r, "d": {"_": r["direct"]}, "e": {"_": r["e2e"]},
                    "ratio": {"_": [{"x": x, "other_cores": max(d["other_cores"], c["other_cores"])}
                                    for x, d, c in zip(r["speedup"], r["direct"], r["compute"]["32"])]}}
                   for r in runs]

        def cells(key: str) -> str:
            vals = [_pool(wrapped, key, b, "fps", max_other) for b in ("16", "32", "64")]
            return " / ".join(f"{v:.0f}" for v, _ in vals) + f" (n={min(k for _, k in vals)})"

        d, nd = _pool(wrapped, "d", "_", "s_per_frame", max_other)
        q, nq = _pool(wrapped, "ratio", "_", "x", max_other)
        e, ne = _pool(wrapped, "e", "_", "fps", max_other)
        es, _ = _pool(wrapped, "e", "_", "fps_incl_sync", max_other)
        su = f"{_median(setups):.1f} (n={len(setups)})" if setups else "-"
        L.append(f"| {case} | {runs[0]['n_vertices']:,} | {su} | {cells('compute')} | {cells('int16')} | "
                 f"{cells('gemm_only')} | {d:.2f} (n={nd}) | {q:.0f}x (n={nq}) | {e:.0f} (n={ne}) | {es:.0f} |")
    L.append("")
    L.append("| take | sink | streamed GB | animate_scan fps | set-up s | peak RSS GB (ru_maxrss) "
             "| of which set-up | after set-up | RSS while streaming, first / last quarter GB | other load, cores |")
    L.append("|---|---|---|---|---|---|---|---|---|---|")
    streams = sorted((r for r in rs if r["mode"] == "stream"), key=lambda r: (r["frames"], r["n_vertices"]))
    for r in streams:
        L.append(f"| {r['case']} x {r['frames']:,} frames | {'/dev/null' if r['sink'] == 'null' else 'vertices.npy'} | "
                 f"{r['streamed_gb']:.1f} | {r['e2e_fps']:.0f} | {r['setup_s']:.1f} | {r['peak_rss_gb']:.2f} | "
                 f"{r['peak_rss_setup_gb']:.2f} | {r['peak_rss_after_setup_gb']:.2f} | "
                 f"{r['rss_stream_first_quarter_max_gb']:.2f} / {r['rss_stream_last_quarter_max_gb']:.2f} | "
                 f"{r['other_cores']:.2f} |")
    setups_rows = [r for r in rs if r["mode"] == "setup"]
    if setups_rows:
        L.append("")
        L.append("| set-up only, backend | mesh | set-up s | peak RSS GB | other load, cores |")
        L.append("|---|---|---|---|---|")
        for r in setups_rows:
            L.append(f"| {r['backend']} | {r['case']} | {r['setup_s']:.1f} | {r['peak_rss_gb']:.2f} | {r['other_cores']:.2f} |")
    return "\n".join(L)


def load_results(paths: list[str]) -> dict[str, Any]:
    """Merge saved ``--all`` payloads (JSON) and files of ``RESULT`` lines into one payload."""
    payload: dict[str, Any] = {"machine": None, "disk": None, "results": []}
    for p in paths:
        text = Path(p).read_text()
        if text.lstrip().startswith("{"):
            d = json.loads(text)
            payload["machine"] = payload["machine"] or d["machine"]
            payload["disk"] = payload["disk"] or d["disk"]
            payload["results"] += d["results"]
        else:
            payload["results"] += [json.loads(ln[7:]) for ln in text.splitlines() if ln.startswith("RESULT ")]
    if payload["machine"] is None:
        payload["machine"] = machine_facts()
    return payload


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--all", action="store_true", help="run every configuration in its own subprocess")
    p.add_argument("--case", choices=_meshes.CASES, default="100k")
    p.add_argument("--mode", choices=("speed", "stream", "setup"), default="speed")
    p.add_argument("--frames", type=int, default=1000)
    p.add_argument("--batch", type=int, default=32, help="frames per deform_into call in the streamed loop")
    p.add_argument("--batches", default="16,32,64", help="batch sizes of the compute-only measurement")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--direct-frames", type=int, default=21, help="solve_direct frames, split over the repeats")
    p.add_argument("--sink", choices=("file", "null"), default="file")
    p.add_argument("--backend", choices=("auto", "pardiso", "scipy"), default="auto")
    p.add_argument("--no-write", action="store_true", help="speed mode: skip the end-to-end writes")
    p.add_argument("--no-int16", action="store_true", help="speed mode: skip the int16 product")
    p.add_argument("--out-dir", default=None, help="where outputs go (default: the system temp folder)")
    p.add_argument("--only", default=None, help="--all: only these cases, e.g. 100k,300k")
    p.add_argument("--save", default=None, help="--all: save the raw results as JSON here")
    p.add_argument("--markdown", nargs="+", default=None,
                   help="print the tables of saved results (--save JSON and/or files of RESULT lines) and exit")
    p.add_argument("--max-other", type=float, default=float("inf"),
                   help="--markdown: pool only repeats during which other processes used at most this many cores")
    args = p.parse_args(argv)
    if args.markdown:
        print(markdown(load_results(args.markdown), max_other=args.max_other))
    elif args.all:
        run_all(args)
    else:
        print("RESULT " + json.dumps(run_one(args)), flush=True)


if __name__ == "__main__":
    main()
