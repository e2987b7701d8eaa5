"""Build ``src/facecap/data/animface_curves.npz``: the 53 ICT expression weights fitted to the real AnimFace take.

The bundled take ``eyebrows.c3d`` (41 markers, 902 frames, 60 Hz, CC BY-SA 4.0) is
conditioned (gaps filled, head motion removed by automatic stabilisation, bilateral
filter: :func:`facecap.markers.condition_take`); its rest frame (frame 0) is aligned
rigidly (:func:`facecap.markers.rigid_fit`) to the ICT marker vertices of
``animface_marker_map()`` raised 1.5 mm along the neutral's vertex normals, and the
same rotation carries every frame's displacement from the rest frame into the ICT
face frame. Each frame's weights solve the bounded, regularised least squares

    min_w |B w - d_t|^2 + lam |w|^2 + mu |w - w_ref|^2,   0 <= w <= 1,

with ``B = expression_deltas[:, marker_vertices]`` (3M x 53), ``d_t`` the
displacements, and ``w_ref`` the previous frame's solution; it runs forwards and
backwards through the take and the two passes are averaged (no lag either way).
The real actor is not the ICT face, so the residual has a floor: even unbounded,
unregularised least squares leaves ~1.34 mm RMS (forehead and brows move more on the
actor than any ICT shape allows).

Usage::

    python tools/build_animface_curves.py            # writes src/facecap/data/animface_curves.npz
    python tools/build_animface_curves.py --out x.npz
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scipy.optimize import lsq_linear

from facecap.io import read_markers
from facecap.markers import condition_take, rigid_fit
from facecap.synth import animface_marker_map, bundled_path, load_ict_sample
from facecap.synth.generate_performance import vertex_normals_at

LAMBDA = 0.5
"""Tikhonov weight on |w|^2 (mm^2 per unit weight^2)."""
MU = 4.0
"""Weight on |w - w_previous|^2, the temporal smoothness."""
OFFSET_MM = 1.5
OUT = Path(__file__).resolve().parents[1] / "src" / "facecap" / "data" / "animface_curves.npz"


def _pass(A: np.ndarray, d: np.ndarray, order: np.ndarray) -> np.ndarray:
    k = A.shape[1]
    W = np.zeros((d.shape[0], k))
    previous = np.zeros(k)
    for t in order:
        b = np.concatenate([d[t], np.zeros(k), np.sqrt(MU) * previous])
        previous = lsq_linear(A, b, bounds=(0.0, 1.0), method="bvls").x
        W[t] = previous
    return W


def build(out: Path) -> dict:
    t0 = time.perf_counter()
    take = read_markers(bundled_path("eyebrows.c3d"))
    conditioned = condition_take(take, stabilize=True)
    marker_map = animface_marker_map()
    labels = list(marker_map)
    index = take.label_index()
    P = conditioned.positions[:, [index[s] for s in labels]]
    mv = np.array([marker_map[s] for s in labels], dtype=np.int64)
    sample = load_ict_sample()
    V, F = sample.mesh.vertices, sample.mesh.faces
    target = V[mv] + OFFSET_MM * vertex_normals_at(V, F, mv)
    align = rigid_fit(P[0], target)
    D = align.apply(P) - align.apply(P[:1])  # displacement from the rest frame, ICT face frame (mm)
    T, M = D.shape[:2]
    d = D.reshape(T, -1)
    B = sample.expression_deltas[:, mv].reshape(len(sample.expression_names), -1).T  # (3M, 53)
    k = B.shape[1]
    A = np.vstack([B, np.sqrt(LAMBDA) * np.eye(k), np.sqrt(MU) * np.eye(k)])
    W = np.clip(0.5 * (_pass(A, d, np.arange(T)) + _pass(A, d, np.arange(T)[::-1])), 0.0, 1.0)  # bvls: -1e-17
    W[0] = 0.0
    residual = np.linalg.norm((W @ B.T - d).reshape(T, M, 3), axis=2)
    zero = np.linalg.norm(D, axis=2)
    unbounded = np.linalg.lstsq(B, d.T, rcond=None)[0].T
    floor = np.linalg.norm((unbounded @ B.T - d).reshape(T, M, 3), axis=2)
    stats = {
        "residual_rms_mm": float(np.sqrt(np.mean(residual**2))),
        "zero_weights_rms_mm": float(np.sqrt(np.mean(zero**2))),
        "unbounded_ls_rms_mm": float(np.sqrt(np.mean(floor**2))),
        "rest_alignment_rms_mm": float(align.rms),
        "seconds": time.perf_counter() - t0,
    }
    provenance = (
        "Fitted by tools/build_animface_curves.py to eyebrows.c3d (AnimFace, Miguel Ramos Carretero, "
        "Bournemouth University 2019, CC BY-SA 4.0): condition_take(stabilize=True), rest frame rigidly "
        f"aligned to the ICT marker vertices + {OFFSET_MM} mm along the normals, bounded least squares "
        f"w in [0, 1]^53 per frame, lambda={LAMBDA}, mu={MU} (previous frame), forward and backward passes "
        "averaged. Licence: CC BY-SA 4.0 (derived from the AnimFace take)."
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        out,
        weights=W.astype(np.float32),
        names=np.array(sample.expression_names),
        rate=np.array(take.rate),
        residual_rms_mm=np.array(stats["residual_rms_mm"]),
        zero_weights_rms_mm=np.array(stats["zero_weights_rms_mm"]),
        unbounded_ls_rms_mm=np.array(stats["unbounded_ls_rms_mm"]),
        marker_residual_rms_mm=np.sqrt(np.mean(residual**2, axis=0)).astype(np.float32),
        marker_labels=np.array(labels),
        stable_labels=np.array(conditioned.stable_labels),
        provenance=np.array(provenance),
        licence=np.array("CC BY-SA 4.0, https://creativecommons.org/licenses/by-sa/4.0/"),
    )
    return stats


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    stats = build(args.out)
    print(args.out, f"{args.out.stat().st_size / 1e3:.0f} kB", stats)


if __name__ == "__main__":
    main()
