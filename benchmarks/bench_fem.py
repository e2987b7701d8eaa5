"""Speed of the flesh finite element model (issue 11, item 2): one quasistatic frame at ~100k tetrahedra.

A structured slab of soft tissue (2 mm cubes, six tetrahedra each, mirrored subdivision),
its bottom face on bone (Dirichlet), 30 muscles as overlapping bands in the upper layers::

    python benchmarks/bench_fem.py --tets 100000 [--muscles 30] [--markdown] [--save out.json]

Measured, with the CPU other processes took meanwhile (``other_cores``, this machine is shared):

1. the kernels at the rest-plus-activation state: energy only, energy and forces, element
   stiffness without and with the definiteness fix, the refill of the CSR values;
2. frame 1 from rest and frame 2 warm-started from frame 1 (activations changed by up to
   +-0.3, as between mocap frames in the paper), by the chosen factorisation (PARDISO)
   and, in the same run, by SciPy's SuperLU: Newton steps and the breakdown (assembly,
   factorisation, solves, line search);
3. the Jacobian of eq. 5 for all muscles at frame 2 (exact stiffness, one factorisation,
   one solve with a right-hand side per muscle);
4. the linear solvers on frame 2's first Newton matrix: PARDISO, SuperLU, CHOLMOD through
   scikit-sparse (where it imports), cholespy (ditto), and CG with a pyamg smoothed-
   aggregation preconditioner (ditto; else incomplete-LU-free Jacobi): factor time, one
   solve, the muscle-count solves, relative residual.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _load import Window  # noqa: E402

from facecap.mesh.factor_spd import SpdFactor, available_backends  # noqa: E402
from facecap.fem import FleshModel, QuasistaticSolver  # noqa: E402
from facecap.fem.flesh_model import _project_psd  # noqa: E402

_KUHN = np.array([[0, 1, 3, 7], [0, 3, 2, 7], [0, 2, 6, 7], [0, 6, 4, 7], [0, 4, 5, 7], [0, 5, 1, 7]])


def slab(target_tets: int, layers: int = 5, cube_mm: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """A square slab ``layers`` cubes thick with about ``target_tets`` tetrahedra (mirrored Kuhn cubes)."""
    side = int(round(np.sqrt(target_tets / (6 * layers))))
    counts = (side, side, layers)
    axes = [np.arange(c + 1) * cube_mm for c in counts]
    X = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    node = np.arange(X.shape[0]).reshape(*(c + 1 for c in counts))
    i, j, k = (a.reshape(-1) for a in np.meshgrid(*(np.arange(c) for c in counts), indexing="ij"))
    flip = np.stack([i % 2, j % 2, k % 2], axis=1)
    corners = np.stack([node[i + ((c & 1) ^ flip[:, 0]), j + (((c >> 1) & 1) ^ flip[:, 1]),
                             k + (((c >> 2) & 1) ^ flip[:, 2])] for c in range(8)], axis=1)
    T = corners[:, _KUHN]
    odd = flip.sum(axis=1) % 2 == 1
    T[odd] = T[odd][:, :, [1, 0, 2, 3]]
    return X, T.reshape(-1, 4).astype(np.int64)


def muscle_bands(X: np.ndarray, T: np.ndarray, n_muscles: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Per-tetrahedron fractions (m, k) and fibre directions (m, k, 3) of bands between random end points."""
    rng = np.random.default_rng(seed)
    centroids = X[T].mean(axis=1)
    extent = X.max(axis=0)
    fractions = np.zeros((T.shape[0], n_muscles))
    directions = np.zeros((T.shape[0], n_muscles, 3))
    for k in range(n_muscles):
        a, b = rng.uniform(0.1, 0.9, size=(2, 2)) * extent[:2]
        axis = np.append(b - a, 0.0)
        length = np.linalg.norm(axis)
        axis /= length
        rel = centroids[:, :2] - a
        along = rel @ axis[:2]
        across = np.abs(rel @ np.array([-axis[1], axis[0]]))
        width = rng.uniform(4.0, 10.0)
        inside = (along > 0) & (along < length) & (across < width) & (centroids[:, 2] > 0.3 * extent[2])
        fractions[inside, k] = np.clip(1.2 - across[inside] / width, 0.2, 1.0)
        directions[inside, k] = axis
    return fractions, directions


def _frame_record(result: Any, wall: dict[str, float]) -> dict[str, Any]:
    return {"wall": wall, "iterations": result.iterations, "projected_steps": result.projected_steps,
            "converged": result.converged, "inverted": result.inverted_tets,
            "residual_mN": result.residual, "breakdown_s": {k: round(v, 3) for k, v in result.timings.items()}}


def timed(fn: Any) -> tuple[Any, dict[str, float]]:
    with Window() as w:
        out = fn()
    return out, {"s": round(w.seconds, 3), "other_cores": round(w.other_cores, 2)}


def linear_solvers(K: sp.csr_matrix, rhs: np.ndarray, cg_rhs: int) -> dict[str, Any]:
    """Factor/solve times and residuals of the available sparse solvers on one SPD matrix."""
    results: dict[str, Any] = {}
    norm = np.linalg.norm(rhs[:, 0])

    def record(name: str, factor: Any, solve: Any, columns: int = rhs.shape[1]) -> None:
        f, tf = timed(factor)
        x1, t1 = timed(lambda: solve(f, rhs[:, :1]))
        xk, tk = timed(lambda: solve(f, rhs[:, :columns]))
        residual = float(np.linalg.norm(K @ np.asarray(x1).reshape(-1) - rhs[:, 0]) / norm)
        results[name] = {"factor": tf, "solve_1": t1, f"solve_{columns}": tk, "relative_residual": residual}

    for backend in available_backends():
        record(f"SpdFactor[{backend}]", lambda b=backend: SpdFactor(K, backend=b), lambda f, b: f.solve(b))
    try:
        from sksparse.cholmod import cholesky

        record("CHOLMOD (scikit-sparse)", lambda: cholesky(K.tocsc()), lambda f, b: f(b))
    except ImportError as exc:
        results["CHOLMOD (scikit-sparse)"] = f"not importable: {exc}"
    try:
        import cholespy

        def factor_cholespy() -> Any:
            coo = K.tocoo()
            return cholespy.CholeskySolverD(K.shape[0], coo.row.astype(np.int32), coo.col.astype(np.int32),
                                            coo.data, cholespy.MatrixType.COO)

        def solve_cholespy(f: Any, b: np.ndarray) -> np.ndarray:
            x = np.zeros_like(b)
            f.solve(np.ascontiguousarray(b), x)
            return x

        record("cholespy (CHOLMOD, bundled BLAS)", factor_cholespy, solve_cholespy)
    except ImportError as exc:
        results["cholespy (CHOLMOD, bundled BLAS)"] = f"not importable: {exc}"
    from scipy.sparse.linalg import cg

    try:
        import pyamg

        def factor_amg() -> Any:
            return pyamg.smoothed_aggregation_solver(K, B=None, symmetry="symmetric").aspreconditioner(cycle="V")

        name = "CG + pyamg SA preconditioner"
    except ImportError:
        def factor_amg() -> Any:
            d = 1.0 / K.diagonal()
            return sp.linalg.LinearOperator(K.shape, matvec=lambda v: d * v)

        name = "CG + Jacobi preconditioner"

    def solve_cg(M: Any, b: np.ndarray) -> np.ndarray:
        out = np.zeros_like(b)
        for c in range(b.shape[1]):
            out[:, c], _ = cg(K, b[:, c], M=M, rtol=1e-8, maxiter=2000)
        return out

    record(name, factor_amg, solve_cg, columns=cg_rhs)
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tets", type=int, default=100_000)
    parser.add_argument("--muscles", type=int, default=30)
    parser.add_argument("--strength", type=float, default=0.05,
                        help="muscle_strength of every muscle (x 300 kPa); 0.05 gives face-like strains of 10-30 %%")
    parser.add_argument("--cg-rhs", type=int, default=2,
                        help="right-hand sides solved by CG (it has no factor to reuse)")
    parser.add_argument("--no-superlu-frames", action="store_true", help="skip the Newton frames with SuperLU")
    parser.add_argument("--markdown", action="store_true")
    parser.add_argument("--save", type=Path)
    args = parser.parse_args()

    (X, T), t_mesh = timed(lambda: slab(args.tets))
    fractions, directions = muscle_bands(X, T, args.muscles)
    bottom = np.flatnonzero(X[:, 2] == 0.0)
    model, t_model = timed(lambda: FleshModel(X, T, fractions, directions, bottom,
                                              muscle_strength=np.full(args.muscles, args.strength)))
    rng = np.random.default_rng(1)
    a1 = rng.uniform(0.0, 0.6, size=args.muscles)
    a2 = np.clip(a1 + rng.uniform(-0.3, 0.3, size=args.muscles), 0.0, 1.0)
    out: dict[str, Any] = {
        "tets": model.n_tets, "nodes": model.n_nodes, "unknowns": int(model.free_dofs.size),
        "muscles": args.muscles, "strength": args.strength, "muscle_tet_pairs": int(np.count_nonzero(fractions)),
        "mesh": t_mesh, "model_setup": t_model,
    }

    # 1. kernels at a deformed state (the frame-1 solution, below, is used for them)
    solver = QuasistaticSolver(model, backend="pardiso" if "pardiso" in available_backends() else "scipy")
    frame1, t1 = timed(lambda: solver.solve(a1, X[bottom]))
    out["frame1"] = _frame_record(frame1, t1)
    x1 = frame1.positions
    kernels: dict[str, Any] = {}
    _, kernels["energy"] = timed(lambda: model.evaluate(x1, a2, derivatives=0))
    _, kernels["energy_forces"] = timed(lambda: model.evaluate(x1, a2, derivatives=1))
    exact, kernels["element_stiffness_exact"] = timed(lambda: model.evaluate(x1, a2, definiteness_fix=False))
    _, kernels["element_stiffness_fixed"] = timed(lambda: model.evaluate(x1, a2))
    A = np.random.default_rng(2).normal(size=(model.n_tets, 9, 9))
    _, kernels["projection_all_indefinite"] = timed(lambda: _project_psd(A))
    model.assemble(exact.element_stiffness)  # the pattern, once
    K, kernels["csr_refill"] = timed(lambda: model.assemble(exact.element_stiffness))
    out["kernels"] = kernels
    out["nnz_free"] = int(K.nnz)

    # 2. frame 2, warm-started, by PARDISO then SuperLU
    frame2, t2 = timed(lambda: solver.solve(a2, X[bottom], x0=x1))
    out["frame2"] = _frame_record(frame2, t2)
    # 3. the eq. 5 Jacobian for every muscle at frame 2
    jac, tj = timed(solver.activation_jacobian)
    out["jacobian_eq5"] = {"wall": tj, "columns": args.muscles, "stiffness": solver.jacobian_stiffness}
    if not args.no_superlu_frames:
        slu = QuasistaticSolver(model, backend="scipy")
        frame2s, t2s = timed(lambda: slu.solve(a2, X[bottom], x0=x1))
        out["frame2_superlu"] = _frame_record(frame2s, t2s)
        out["frame2_superlu"]["max_difference_mm"] = float(np.abs(frame2s.positions - frame2.positions).max())
    # 4. the linear solvers on an SPD Newton matrix of frame 2 (the projected stiffness at x1 under a2)
    K_newton = model.stiffness(x1, a2, free_only=True)
    rhs = model.force_basis(x1).reshape(args.muscles, -1)[:, model.free_dofs].T.copy()
    out["linear_solvers"] = linear_solvers(K_newton, rhs, args.cg_rhs)
    print("RESULT " + json.dumps(out))
    if args.save:
        args.save.write_text(json.dumps(out, indent=2))
    if args.markdown:
        print(markdown(out))


def markdown(out: dict[str, Any]) -> str:
    lines = [f"{out['tets']:,} tetrahedra, {out['unknowns']:,} unknowns, {out['muscles']} muscles "
             f"({out['muscle_tet_pairs']:,} muscle-tet pairs), free stiffness nnz {out['nnz_free']:,}", "",
             "| frame | backend | Newton steps (projected) | wall s | assembly | factorisation | solves | line search |",
             "|---|---|---|---|---|---|---|---|"]
    for key, backend in (("frame1", "PARDISO"), ("frame2", "PARDISO"), ("frame2_superlu", "SuperLU")):
        if key in out:
            f = out[key]
            b = f["breakdown_s"]
            lines.append(f"| {key[:6]} | {backend} | {f['iterations']} ({f['projected_steps']}) | {f['wall']['s']} | "
                         f"{b['assembly']} | "
                         f"{b['factorisation']} | {b['solves']} | {b['line_search']} |")
    j = out["jacobian_eq5"]
    lines += ["", f"eq. 5 Jacobian, {j['columns']} columns ({j['stiffness']} stiffness): {j['wall']['s']} s", "",
              "| kernel | s |", "|---|---|"]
    lines += [f"| {k} | {v['s']} |" for k, v in out["kernels"].items()]
    lines += ["", "| linear solver | factor s | 1 solve s | more solves (count) s | relative residual |",
              "|---|---|---|---|---|"]
    for name, r in out["linear_solvers"].items():
        if isinstance(r, str):
            lines.append(f"| {name} | {r} | | | |")
            continue
        key, many = [(k, v) for k, v in r.items() if k.startswith("solve_") and k != "solve_1"][0]
        lines.append(f"| {name} | {r['factor']['s']} | {r['solve_1']['s']} | {many['s']} ({key[6:]}) | "
                     f"{r['relative_residual']:.1e} |")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
