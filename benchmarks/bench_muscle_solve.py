"""Speed of the muscle solve (issue 11, the "Speed" bar): anatomy build and seconds per frame at ~100k tetrahedra.

The bar: on 2 cores, at most 10 s per frame at about 100k tetrahedra after the first frame, the
anatomy built in at most 5 minutes, with the breakdown beside a plain baseline in the same run::

    python benchmarks/bench_muscle_solve.py [--tets 100000] [--frames 6] [--threads 2] \\
        [--markdown results.md] [--json results.json]
    python benchmarks/bench_muscle_solve.py --quick        # 2,000 requested tetrahedra, 3 frames: < 1 minute

What runs, in one process:

1. ``build_anatomy(load_ict_sample().mesh, n_tets=N)``, timed (the bar: 300 s); default N is the
   package's (100,000 requested: about 96k tetrahedra, 21k nodes, 51k unknowns).
2. A take from the forward model with known controls, solved by a **second** ``MuscleModel`` (the
   truth), so the solves below share no state with it: 120 markers 1.5 mm above the skin placed
   by ``facecap.synth.choose_marker_vertices`` (denser where the muscles and the jaw move the skin,
   as in ``tests/muscles/conftest.py``), 0.2 mm Gaussian noise per coordinate. Frame 0 is a random
   expression (about half the muscles active up to 0.7, the jaw opened 2-15 degrees with slides up
   to 3 mm, the head turned by about 3 degrees and moved 5 mm); every later frame changes each
   active muscle by up to +-0.1, the head by up to 1 degree and 1 mm, the jaw by up to 1 degree
   and 0.3 mm of slide: the take of docs/muscles.md's "Measured".
3. ``MuscleSolver.solve_frame`` over the take, frame 0 cold (from rest, up to 5 Gauss-Newton
   steps), the rest warm-started from the frame before (up to 2), once with the chosen sparse
   factorisation (``backend='pardiso'``, MKL PARDISO through pypardiso) and once with the plain
   baseline (``backend='scipy'``, SciPy's SuperLU) on the same frames (``--baseline-frames``
   limits the baseline to its first frames; ``--baseline-start chosen`` has it start its warm frames
   from the chosen backend's frame 0 instead of solving frame 0 itself). Each backend gets its own
   ``MuscleSolver`` and model.

   Note: the baseline is not quite the same algorithm with a slower factorisation. SpdFactor's
   'scipy' backend factors indefinite matrices without complaint (SuperLU, no pivoting), where
   PARDISO's SPD mode refuses them and the quasistatic Newton falls back to the projected
   stiffness; so far from equilibrium (a cold frame) SuperLU's Newton takes other steps, often
   many more, and may end in another equilibrium. The accuracy columns and the largest activation
   difference between the backends show when it did.

Per backend: the cold frame, the median and largest warm frame, the breakdown of a warm frame
(mean over the warm frames, s):

* ``quasistatic``: the equilibria outside the line search (the full steps, warm-started by the
  linearised prediction, and the re-solves at the start of a step), ``MuscleFrame.timings``'
  ``full_step`` plus ``linearise`` less the Jacobians;
* ``jacobians``: the linearisation proper, the factorisation of the exact stiffness
  (``jacobian_factor``) and the multi-right-hand-side eq. 5 and 6 solves, plus the marker
  Jacobian's assembly (timed here by wrapping ``MuscleSolver._jacobian``, ``MuscleModel.jacobians``
  and ``QuasistaticSolver.factor`` on the instance; nothing in the package changes);
* ``line_search`` (the golden-section trials), ``continuation`` (the penalty continuation on the
  small system, ``gauss_newton``), ``other`` (the rest of ``total``: objective, flags, skin);
* inside the quasistatic Newton solves (all of them, the line search's included), from
  ``QuasistaticResult.timings``: ``newton_assembly``, ``newton_factorisation``,
  ``newton_solves``, ``newton_line_search``;

plus Gauss-Newton steps, quasistatic solves and Newton iterations per frame, the accuracy against
the known controls (activations mean absolute error, jaw opening error, head angle error, marker
rms: a fast wrong answer shows), flags and inverted tetrahedra, the largest activation difference
between the two backends' frames, and the ratio baseline / chosen of the median warm frame.

Threads: ``--threads`` (default 2, the bar's cores) caps BLAS and MKL (PARDISO) threads through
threadpoolctl around the solves; ``facecap solve-muscles`` runs its frames in
``MuscleFrameStage``, which pins **one** thread per worker (and runs one worker per core), so
``--threads 1`` is the per-worker figure of the command line. The anatomy build runs with the
library defaults. Every timed block also records the CPU other processes used meanwhile
(``other_cores``, from ``/proc/stat``): this machine is shared, and a figure taken while others ran
is an upper bound. Peak resident memory (``ru_maxrss``) is recorded after each stage; it only grows,
so the baseline's figure includes everything before it.
"""

from __future__ import annotations

import argparse
import importlib.metadata as md
import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np
from scipy.spatial.transform import Rotation
from threadpoolctl import threadpool_info, threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _load import Window, peak_rss_gb  # noqa: E402

from facecap.anatomy import build_anatomy, load_anatomy  # noqa: E402
from facecap.mesh.factor_spd import available_backends  # noqa: E402
from facecap.muscles import (MuscleControls, MuscleFrame, MuscleModel, MuscleSolver, forward_markers,  # noqa: E402
                             marker_embedding)
from facecap.synth import choose_marker_vertices  # noqa: E402
from facecap.io.ict_sample import load_ict_sample

DEFAULT_TETS = 100_000  # build_anatomy's default
N_MARKERS = 120
MARKER_LIFT_MM = 1.5
NOISE_MM = 0.2
BACKEND_NAMES = {"pardiso": "PARDISO (MKL, pypardiso)", "scipy": "SuperLU (SciPy), baseline"}
BREAKDOWN = ("quasistatic", "jacobians", "jacobian_factor", "line_search", "continuation", "other",
             "newton_assembly", "newton_factorisation", "newton_solves", "newton_line_search")


# -- machine -----------------------------------------------------------------------------------------
def machine_facts() -> dict[str, Any]:
    """CPU model, cores, memory, numpy's BLAS and the versions that matter here."""
    facts: dict[str, Any] = {"cpu": "unknown"}
    with open("/proc/cpuinfo") as f:
        for line in f:
            if line.startswith("model name"):
                facts["cpu"] = line.split(":", 1)[1].strip()
                break
    facts["cores"] = os.cpu_count()
    with open("/proc/meminfo") as f:
        facts["ram_gb"] = round(int(f.readline().split()[1]) * 1024 / 1e9, 1)
    blas = np.show_config(mode="dicts")["Build Dependencies"]["blas"]
    facts["numpy"] = np.__version__
    facts["numpy_blas"] = f"{blas['name']} {blas.get('version', '')}".strip()
    for pkg in ("scipy", "pypardiso", "mkl", "pytetwild", "threadpoolctl"):
        try:
            facts[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            facts[pkg] = "not installed"
    facts["python"] = sys.version.split()[0]
    facts["env_threads"] = {k: os.environ[k] for k in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
                            if k in os.environ}
    facts["loadavg_start"] = [round(x, 2) for x in os.getloadavg()]
    return facts


def machine_line(facts: dict[str, Any]) -> str:
    return (f"{facts['cpu']}, {facts['cores']} cores, {facts['ram_gb']} GB; Python {facts['python']}, "
            f"numpy {facts['numpy']} ({facts['numpy_blas']}), scipy {facts['scipy']}, pypardiso {facts['pypardiso']}, "
            f"mkl {facts['mkl']}; load average at start {facts['loadavg_start']}")


def _threads_in_use() -> list[str]:
    return sorted({f"{p.get('internal_api')}={p.get('num_threads')}" for p in threadpool_info()})


# -- the take -----------------------------------------------------------------------------------------
def marker_layout(anatomy: Any, model: MuscleModel) -> tuple[np.ndarray, np.ndarray]:
    """120 marker vertices, denser where the muscles and the jaw move the skin, and their rest markers 1.5 mm out."""
    model.equilibrium(np.zeros(model.n_muscles), np.eye(3, 4))
    dXa, dXb = model.jacobians()
    rest_skin = model.skin(model.rest_positions)
    deltas = np.stack([model.skin(model.rest_positions + d) - rest_skin for d in np.concatenate([dXa, 0.2 * dXb[:9]])])
    V, F = anatomy.scan_vertices, anatomy.scan_faces
    vertices = choose_marker_vertices(V, F, deltas, N_MARKERS, exclude=~(anatomy.skin_meshed & model.skin_follows))
    normals = np.zeros_like(V)
    face_normals = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    for corner in range(3):
        np.add.at(normals, F[:, corner], face_normals)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return vertices, V[vertices] + MARKER_LIFT_MM * normals[vertices]


def take_controls(model: MuscleModel, n_frames: int, seed: int) -> list[MuscleControls]:
    """A random expression, then small changes per frame (muscles +-0.1, head 1 degree / 1 mm, jaw 1 degree)."""
    rng = np.random.default_rng(seed)
    k = model.n_muscles
    active = rng.uniform(size=k) < 0.5
    a = rng.uniform(0, 0.7, k) * active
    opening = np.radians(rng.uniform(2.0, 15.0))
    slides = rng.uniform(0, 3, 2)
    rotvec = rng.normal(0, 0.05, 3)  # about 3 degrees
    shift = rng.normal(0, 5.0 / np.sqrt(3), 3)  # about 5 mm
    out = []
    for t in range(n_frames):
        if t:
            a = np.clip(a + rng.uniform(-0.1, 0.1, k) * active, 0.0, 1.0)
            opening = float(np.clip(opening + np.radians(rng.uniform(-1, 1)), np.radians(1.0), np.radians(25.0)))
            slides = np.clip(slides + rng.uniform(-0.3, 0.3, 2), 0.0, 5.0)
            turn = rng.normal(size=3)
            rotvec = rotvec + np.radians(rng.uniform(0, 1)) * turn / np.linalg.norm(turn)
            step = rng.normal(size=3)
            shift = shift + rng.uniform(0, 1) * step / np.linalg.norm(step)
        cranium = np.hstack([Rotation.from_rotvec(rotvec).as_matrix(), shift[:, None]])
        out.append(MuscleControls(a.copy(), cranium, model.jaw.transform(opening, *slides)))
    return out


def _angle_deg(A: np.ndarray, B: np.ndarray) -> float:
    """Angle of the rotation between the rigid parts of two (3, 4) frames."""
    U, _, Vt = np.linalg.svd(A[:, :3])
    R = (U @ Vt).T @ B[:, :3]
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))))


# -- the instrumented solve -----------------------------------------------------------------------------
class _Clock:
    """Seconds spent in wrapped callables, by name (reset per frame)."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self.newton: dict[str, float] = {}

    def reset(self) -> None:
        self.seconds = {"marker_jacobian": 0.0, "model_jacobians": 0.0, "jacobian_factor": 0.0}
        self.newton = {"assembly": 0.0, "factorisation": 0.0, "solves": 0.0, "line_search": 0.0}
        self.projected_steps = 0

    def wrap(self, name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        def timed(*args: Any, **kwargs: Any) -> Any:
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - t0
        return timed

    def wrap_newton(self, fn: Callable[..., Any]) -> Callable[..., Any]:
        def solve(*args: Any, **kwargs: Any) -> Any:
            result = fn(*args, **kwargs)
            for key, value in result.timings.items():
                self.newton[key] = self.newton.get(key, 0.0) + value
            self.projected_steps += int(result.projected_steps)
            return result
        return solve


def instrument(solver: MuscleSolver) -> _Clock:
    """Time the linearisation's parts on this solver's instances (instance attributes shadow the methods)."""
    clock = _Clock()
    clock.reset()
    solver._jacobian = clock.wrap("marker_jacobian", solver._jacobian)  # type: ignore[method-assign]
    solver.model.jacobians = clock.wrap("model_jacobians", solver.model.jacobians)  # type: ignore[method-assign]
    qs = solver.model.solver
    qs.factor = clock.wrap("jacobian_factor", qs.factor)  # type: ignore[method-assign]
    qs.solve = clock.wrap_newton(qs.solve)  # type: ignore[method-assign]
    return clock


def breakdown(timings: dict[str, float], clock: _Clock) -> dict[str, float]:
    jac = clock.seconds["marker_jacobian"]
    out = {
        "quasistatic": timings["full_step"] + timings["linearise"] - jac,
        "jacobians": jac,
        "jacobian_factor": clock.seconds["jacobian_factor"],
        "line_search": timings["line_search"],
        "continuation": timings["gauss_newton"],
    }
    out["other"] = timings["total"] - (out["quasistatic"] + jac + out["line_search"] + out["continuation"])
    out.update({f"newton_{k}": v for k, v in clock.newton.items()})
    return {k: round(v, 4) for k, v in out.items()}


def solve_take(anatomy: Any, vertices: np.ndarray, rest_markers: np.ndarray, markers: np.ndarray,
               truth: list[MuscleControls], backend: str, threads: int,
               start: MuscleFrame | None = None) -> tuple[dict[str, Any], list[MuscleFrame]]:
    """Solve the take's frames with one backend; times, breakdown and accuracy per frame.

    ``start``: a solved frame 0 (another backend's) to warm-start frame 1 from; frame 0 is then
    not solved here (and the first warm frame also solves its starting equilibrium once).
    """
    with Window() as w:
        solver = MuscleSolver(anatomy, vertices, rest_markers, backend=backend)
    setup = {"s": round(w.seconds, 3), "other_cores": round(w.other_cores, 2)}
    clock = instrument(solver)
    frames: list[dict[str, Any]] = []
    solved: list[MuscleFrame] = [] if start is None else [start]
    previous = start
    with threadpool_limits(limits=threads):
        threads_seen = _threads_in_use()
        for t in range(0 if start is None else 1, markers.shape[0]):
            clock.reset()
            with Window() as w:
                frame = solver.solve_frame(markers[t], previous=previous)
            c = truth[t]
            jaw_true = solver.model.jaw.pose(c.mandible)
            record = {
                "frame": t, "cold": previous is None, "s": round(w.seconds, 3),
                "other_cores": round(w.other_cores, 2), "my_cores": round(w.my_cores, 2),
                "steps": frame.steps, "quasistatic_solves": frame.quasistatic_solves,
                "newton_iterations": frame.newton_iterations, "projected_newton_steps": clock.projected_steps,
                "breakdown_s": breakdown(frame.timings, clock), "timings_s": dict(frame.timings),
                "activation_mae": float(np.abs(frame.activations - c.activations).mean()),
                "activation_max_error": float(np.abs(frame.activations - c.activations).max()),
                "jaw_opening_error_deg": float(np.degrees(abs(frame.jaw_pose[0] - jaw_true[0]))),
                "jaw_slide_error_mm": float(np.abs(frame.jaw_pose[1:] - jaw_true[1:]).max()),
                "head_angle_error_deg": _angle_deg(frame.cranium, c.cranium),
                "marker_rms_mm": frame.rms_mm, "inverted_tets": frame.inverted_tets,
                "constraint_violation": max(frame.constraint_violation.values()), "flags": list(frame.flags),
            }
            frames.append(record)
            solved.append(frame)
            previous = frame
            print(f"  {backend} frame {t} ({'cold' if record['cold'] else 'warm'}): {record['s']:.2f} s, "
                  f"{record['steps']} steps, {record['quasistatic_solves']} solves, "
                  f"{record['newton_iterations']} Newton ({record['projected_newton_steps']} projected), "
                  f"activations MAE {record['activation_mae']:.3f}, "
                  f"rms {record['marker_rms_mm']:.3f} mm, other cores {record['other_cores']}", flush=True)
    warm = [f for f in frames if not f["cold"]]
    summary: dict[str, Any] = {
        "backend": backend, "name": BACKEND_NAMES.get(backend, backend), "solver_setup": setup,
        "threads": threads_seen, "frames": frames, "n_frames": len(frames), "n_warm": len(warm),
        "frames_covered": int(markers.shape[0]),
        "started_from_other_backend": start is not None,
        "cold_s": frames[0]["s"] if start is None else None,
        "cold_steps": frames[0]["steps"] if start is None else None,
        "cold_newton": frames[0]["newton_iterations"] if start is None else None,
        "cold_projected": frames[0]["projected_newton_steps"] if start is None else None,
        "activation_mae": float(np.mean([f["activation_mae"] for f in frames])),
        "activation_mae_max": max(f["activation_mae"] for f in frames),
        "jaw_opening_error_deg_max": max(f["jaw_opening_error_deg"] for f in frames),
        "head_angle_error_deg_max": max(f["head_angle_error_deg"] for f in frames),
        "marker_rms_mm": [min(f["marker_rms_mm"] for f in frames), max(f["marker_rms_mm"] for f in frames)],
        "inverted_tets_max": max(f["inverted_tets"] for f in frames),
        "constraint_violation_max": max(f["constraint_violation"] for f in frames),
        "flagged_frames": {f["frame"]: f["flags"] for f in frames if f["flags"]},
        "other_cores_mean": round(float(np.mean([f["other_cores"] for f in frames])), 2),
        "peak_rss_gb": round(peak_rss_gb(), 2),
    }
    if warm:
        times = [f["s"] for f in warm]
        summary.update({
            "warm_median_s": statistics.median(times), "warm_max_s": max(times), "warm_min_s": min(times),
            "warm_breakdown_s": {k: round(float(np.mean([f["breakdown_s"][k] for f in warm])), 3) for k in BREAKDOWN},
            "warm_steps": float(np.mean([f["steps"] for f in warm])),
            "warm_solves": float(np.mean([f["quasistatic_solves"] for f in warm])),
            "warm_newton": float(np.mean([f["newton_iterations"] for f in warm])),
            "warm_projected": float(np.mean([f["projected_newton_steps"] for f in warm])),
        })
    return summary, solved


# -- the run ------------------------------------------------------------------------------------------
def run(args: argparse.Namespace) -> dict[str, Any]:
    facts = machine_facts()
    print("machine:", machine_line(facts), flush=True)
    out: dict[str, Any] = {"machine": facts, "options": {k: (str(v) if isinstance(v, Path) else v)
                                                         for k, v in vars(args).items()}}
    reuse = args.anatomy is not None and (args.anatomy / "anatomy.json").is_file()
    with Window() as w:
        if reuse:
            anatomy = load_anatomy(args.anatomy)
        else:
            anatomy = build_anatomy(load_ict_sample().mesh, n_tets=args.tets, progress=False)
    if args.anatomy is not None and not reuse:
        anatomy.save(args.anatomy)
    out["anatomy"] = {"s": None if reuse else round(w.seconds, 2), "loaded_from": str(args.anatomy) if reuse else None,
                      "other_cores": round(w.other_cores, 2),
                      "stages_s": {k: round(float(v), 2) for k, v in anatomy.provenance.get("seconds", {}).items()},
                      "requested_tets": None if reuse else args.tets, "tets": int(anatomy.tets.shape[0]),
                      "nodes": int(anatomy.nodes.shape[0]), "muscles": len(anatomy.muscle_names),
                      "peak_rss_gb": round(peak_rss_gb(), 2)}
    backends = available_backends()
    chosen = "pardiso" if "pardiso" in backends else "scipy"
    if chosen != "pardiso":
        print("warning: PARDISO does not load here; the chosen backend falls back to SuperLU", flush=True)
    with Window() as w, threadpool_limits(limits=args.threads):
        truth_model = MuscleModel(anatomy, backend=chosen)
        vertices, rest_markers = marker_layout(anatomy, truth_model)
        embedding = marker_embedding(anatomy, vertices, rest_markers)
        truth = take_controls(truth_model, args.frames, args.seed)
        markers, x0, forward_iterations = [], None, []
        for t, c in enumerate(truth):
            f = forward_markers(truth_model, embedding, c, x0=x0, noise_mm=NOISE_MM, seed=args.seed * 1000 + t)
            x0 = f.result.positions
            markers.append(f.markers)
            forward_iterations.append(int(f.result.iterations))
    out["anatomy"]["unknowns"] = int(truth_model.flesh.free_dofs.size)
    out["anatomy"]["dirichlet_nodes"] = int(truth_model.cranium_set.size + truth_model.mandible_set.size)
    out["take"] = {"s": round(w.seconds, 2), "other_cores": round(w.other_cores, 2), "frames": args.frames,
                   "markers": int(vertices.size), "noise_mm": NOISE_MM, "forward_newton_iterations": forward_iterations,
                   "jaw_opening_deg": [round(float(np.degrees(truth_model.jaw.pose(c.mandible)[0])), 2) for c in truth],
                   "active_muscles": int((truth[0].activations > 0).sum())}
    del truth_model
    a = out["anatomy"]
    built = f"loaded from {a['loaded_from']} (build not timed)" if reuse else f"built in {a['s']:.1f} s"
    print(f"anatomy: {a['tets']:,} tetrahedra, {a['nodes']:,} nodes, {a['unknowns']:,} unknowns, "
          f"{a['muscles']} muscles, {built} (other cores {a['other_cores']}); "
          f"take of {args.frames} frames made in {out['take']['s']:.1f} s", flush=True)
    markers_all = np.stack(markers)
    out["runs"] = {}
    solved = {}
    baseline_n = args.frames if args.baseline_frames is None else min(args.baseline_frames, args.frames)
    wanted = baseline_n > (1 if args.baseline_start == "chosen" else 0)  # frames left for it to solve
    order = [chosen] + (["scipy"] if chosen != "scipy" and wanted else [])
    for backend in order:
        n = args.frames if backend == chosen else baseline_n
        print(f"{BACKEND_NAMES[backend]}: {n} frames, {args.threads} thread(s)", flush=True)
        start = solved[chosen][0] if backend != chosen and args.baseline_start == "chosen" else None
        out["runs"][backend], solved[backend] = solve_take(anatomy, vertices, rest_markers, markers_all[:n],
                                                           truth[:n], backend, args.threads, start=start)
    if len(solved) == 2:
        n = min(len(v) for v in solved.values())
        base, fast = out["runs"]["scipy"], out["runs"][chosen]
        first = 0 if args.baseline_start == "cold" else 1
        diff = max((float(np.abs(solved["scipy"][t].activations - solved[chosen][t].activations).max())
                    for t in range(first, n)), default=0.0)
        out["comparison"] = {"activation_max_difference": diff, "frames_compared": n - first}
        if "warm_median_s" in base and "warm_median_s" in fast:
            out["comparison"]["warm_median_ratio"] = round(base["warm_median_s"] / fast["warm_median_s"], 2)
        if base["cold_s"] is not None:
            out["comparison"]["cold_ratio"] = round(base["cold_s"] / fast["cold_s"], 2)
    out["peak_rss_gb"] = round(peak_rss_gb(), 2)
    out["loadavg_end"] = [round(x, 2) for x in os.getloadavg()]
    return out


def markdown(out: dict[str, Any]) -> str:
    a, take, opts = out["anatomy"], out["take"], out["options"]
    runs = out["runs"]
    if a["s"] is None:
        built = f"loaded from `{a['loaded_from']}` (`--anatomy`): the build is **not timed** in this run"
        where = "a saved model"
    else:
        built = f"built in **{a['s']:.1f} s** (bar 300 s; other processes {a['other_cores']} cores meanwhile)"
        where = f"the ICT face at `n_tets={a['requested_tets']}`"
    lines = [f"Machine: {machine_line(out['machine'])}.", "",
             f"Anatomy: {where}: **{a['tets']:,} tetrahedra**, {a['nodes']:,} nodes, {a['unknowns']:,} unknowns, "
             f"{a['muscles']} muscles; {built}.", "",
             f"Take: {take['frames']} frames from a second model with known controls, {take['markers']} markers "
             f"{MARKER_LIFT_MM} mm above the skin, {take['noise_mm']} mm noise, jaw opening "
             f"{min(take['jaw_opening_deg'])}-{max(take['jaw_opening_deg'])} degrees, head moving; "
             f"{opts['threads']} BLAS/MKL thread(s) (threadpoolctl) for the solves.", "",
             "| backend | frames (warm) | cold frame s (steps, Newton) | warm median s | warm max s "
             "| steps / solves / Newton (projected) per warm frame "
             "| activations MAE (worst frame) | jaw / head error deg | marker rms mm | flags | other cores |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in runs.values():
        warm = "- | - | -"
        if r["n_warm"]:
            warm = (f"{r['warm_median_s']:.2f} | {r['warm_max_s']:.2f} | {r['warm_steps']:.1f} / "
                    f"{r['warm_solves']:.1f} / {r['warm_newton']:.1f} ({r['warm_projected']:.1f})")
        cold = ("from the chosen backend's frame 0" if r["cold_s"] is None
                else f"{r['cold_s']:.2f} ({r['cold_steps']}, {r['cold_newton']})")
        flags = ", ".join(f"{k}: {'+'.join(v)}" for k, v in r["flagged_frames"].items()) or "none"
        lines.append(f"| {r['name']} | {r['n_frames']} ({r['n_warm']}) | {cold} | {warm} | "
                     f"{r['activation_mae']:.3f} ({r['activation_mae_max']:.3f}) | "
                     f"{r['jaw_opening_error_deg_max']:.3f} / {r['head_angle_error_deg_max']:.3f} | "
                     f"{r['marker_rms_mm'][0]:.3f}-{r['marker_rms_mm'][1]:.3f} | {flags} | {r['other_cores_mean']} |")
    with_warm = [r for r in runs.values() if r["n_warm"]]
    if with_warm:
        lines += ["", "Breakdown of a warm frame (mean, s): quasistatic = equilibria outside the line search; "
                  "jacobians = exact-stiffness factorisation + eq. 5/6 solves + marker Jacobian; "
                  "the newton_* columns split all quasistatic Newton solves (line search's included).", "",
                  "| backend | total | quasistatic | jacobians (of which factor) | line search | continuation | other "
                  "| Newton assembly | Newton factorisation | Newton solves | Newton line search |",
                  "|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in with_warm:
            b = r["warm_breakdown_s"]
            total = statistics.mean(f["s"] for f in r["frames"] if not f["cold"])
            lines.append(f"| {r['name']} | {total:.2f} | {b['quasistatic']:.2f} | {b['jacobians']:.2f} "
                         f"({b['jacobian_factor']:.2f}) | {b['line_search']:.2f} | {b['continuation']:.2f} | "
                         f"{b['other']:.2f} | {b['newton_assembly']:.2f} | {b['newton_factorisation']:.2f} | "
                         f"{b['newton_solves']:.2f} | {b['newton_line_search']:.2f} |")
    if "comparison" in out:
        c = out["comparison"]
        ratio = f"**{c['warm_median_ratio']:.2f}x**" if "warm_median_ratio" in c else "n/a"
        cold = f", cold frame {c['cold_ratio']:.2f}x" if "cold_ratio" in c else ""
        lines += ["", f"Baseline / chosen: warm-frame median {ratio}{cold}; the two "
                  f"backends' activations differ by at most {c['activation_max_difference']:.1e} over "
                  f"{c['frames_compared']} frames."]
        if c["activation_max_difference"] > 1e-3:
            lines.append("**The backends' answers differ**: SuperLU factors indefinite matrices (SpdFactor's 'scipy' "
                         "backend does not refuse them as PARDISO's SPD mode does), so where the exact stiffness is "
                         "indefinite the quasistatic Newton takes other steps and may reach another equilibrium; "
                         "compare the accuracy columns before the times.")
        if runs["scipy"]["frames_covered"] < runs[next(iter(runs))]["frames_covered"]:
            lines.append(f"The baseline solved only the first {runs['scipy']['frames_covered']} frames "
                         "(`--baseline-frames`).")
        if runs["scipy"]["started_from_other_backend"]:
            lines.append("The baseline did not solve frame 0: its warm frames start from the chosen backend's "
                         "frame 0 (`--baseline-start chosen`); its first warm frame also solves that starting "
                         "equilibrium once.")
    lines += ["", f"Peak memory (ru_maxrss): {a['peak_rss_gb']} GB after the anatomy, "
              + ", ".join(f"{r['peak_rss_gb']} GB after {r['backend']}" for r in runs.values())
              + f"; load average at the end {out['loadavg_end']}."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--tets", type=int, default=DEFAULT_TETS,
                   help="tetrahedra asked of build_anatomy (default the package's, 100,000: about 96k)")
    p.add_argument("--frames", type=int, default=6, help="frames of the take: 1 cold + the rest warm (default 6)")
    p.add_argument("--baseline-frames", type=int, default=None,
                   help="solve only the first this many frames with the SuperLU baseline (default all; 0 skips it)")
    p.add_argument("--baseline-start", choices=("cold", "chosen"), default="cold",
                   help="the baseline's frame 0: solved cold by itself (default), or taken from the chosen backend's "
                        "result so the baseline solves only the warm frames (its cold frame can take many minutes at "
                        "100k: SuperLU accepts indefinite Newton matrices and the cold solve wanders)")
    p.add_argument("--threads", type=int, choices=(1, 2), default=2,
                   help="BLAS/MKL threads for the solves (threadpoolctl); solve-muscles' workers use 1")
    p.add_argument("--seed", type=int, default=3)
    p.add_argument("--anatomy", type=Path, default=None,
                   help="a model folder: loaded if it holds one (the build is then not timed), else built and saved "
                        "there (fTetWild's mesh differs from build to build; this repeats a run on the same mesh)")
    p.add_argument("--quick", action="store_true", help="n_tets=2000, 3 frames: a check that it runs (< 1 minute)")
    p.add_argument("--markdown", type=Path, default=None, help="write the markdown tables here")
    p.add_argument("--json", type=Path, default=None, help="write every figure as JSON here")
    args = p.parse_args(argv)
    if args.quick:
        args.tets, args.frames = 2000, 3
    if args.frames < 1:
        p.error("--frames must be at least 1")
    t0 = time.perf_counter()
    out = run(args)
    out["wall_s"] = round(time.perf_counter() - t0, 1)
    text = markdown(out)
    print()
    print(text)
    print(f"\nwhole run {out['wall_s']} s")
    if args.markdown:
        args.markdown.write_text(text + "\n")
    if args.json:
        args.json.write_text(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
