"""The detail layer's bars, measured against the generator's truth (issue 30): both placements, nothing invented.

With ``A`` the layer below, ``D`` the detail result, ``G`` the truth and ``L`` the truth without the
expression-driven detail, at the mocap frames of the video frames:

- vertex by vertex: ``mean |(D - A) - (G - L)|`` over ``mean |G - L|``, where ``|G - L| > 0.03 mm``;
- in space: the target at each vertex of ``A`` is the true detail height of the ``L`` vertex nearest to it,
  along the normal; ``mean |h_D - target|`` over ``mean |target|``, counted where ``|target|`` or
  ``|D - A|`` exceeds 0.03 mm (``h_D`` the added displacement along ``A``'s normal);
- nothing invented: mean ``|D - A|`` where the truth has no expression-driven detail (outside
  ``detail_mask``, away from markers and the mesh boundary), and on freckles, moles, brows and markers;
- stable in time: frame-to-frame RMS change of ``D - A`` over all frames, and over the pairs of frames where
  the expression holds (the lines present, their activations changing by less than 0.01 between the two).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

THRESHOLD_MM = 0.03


def detail_metrics(case: Path, base: Path, detail, *, frames: np.ndarray | None = None) -> dict:
    """The metrics of a detail result folder ``detail``, or of ``detail(t, A) -> D`` (mocap frame, layer below)."""
    from scipy.spatial import cKDTree

    from facecap.io.read_result import read_result
    from facecap.mesh.vertex_normals import vertex_normals

    truth = np.load(case / "truth.npz")
    video = truth["video_mocap_frames"] if frames is None else frames
    A_res = read_result(base)
    D_res = read_result(detail) if isinstance(detail, (str, Path)) else None
    F = A_res.mesh.faces
    n = A_res.n_vertices
    sums = dict(v_err=0.0, v_size=0.0, s_err=0.0, s_size=0.0, flat=0.0, flat_n=0, marks=0.0, marks_n=0)
    invented_mask = ~truth["detail_mask"].astype(bool)
    marks = truth["freckle_mask"] | truth["mole_mask"] | truth["brow_mask"] | truth["marker_mask"]
    boundary = np.zeros(n, dtype=bool)
    edges = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    boundary[unique[counts == 1].ravel()] = True
    flat = invented_mask & ~truth["marker_mask"] & ~boundary
    added_series = []
    for t in video:
        A = A_res.frames(int(t), int(t) + 1)[0].astype(np.float64)
        D = D_res.frames(int(t), int(t) + 1)[0].astype(np.float64) if D_res is not None else detail(int(t), A)
        G = truth["vertices"][t].astype(np.float64)
        L = truth["without_detail"][t].astype(np.float64)
        added = D - A
        true = G - L
        size = np.linalg.norm(true, axis=1)
        on = size > THRESHOLD_MM
        sums["v_err"] += np.linalg.norm(added - true, axis=1)[on].sum()
        sums["v_size"] += size[on].sum()
        NA = vertex_normals(A, F, np.arange(n))
        h_D = np.sum(added * NA, axis=1)
        nearest = cKDTree(L).query(A)[1]
        target = truth["detail_height"][t][nearest]
        count = (np.abs(target) > THRESHOLD_MM) | (np.abs(h_D) > THRESHOLD_MM)
        sums["s_err"] += np.abs(h_D - target)[count].sum()
        sums["s_size"] += np.abs(target)[count].sum()
        a = np.linalg.norm(added, axis=1)
        sums["flat"] += a[flat].sum()
        sums["flat_n"] += int(flat.sum())
        sums["marks"] += a[marks].sum()
        sums["marks_n"] += int(marks.sum())
        added_series.append(added)
    series = np.stack(added_series)
    activation = truth["activation"][video]
    held = (np.abs(np.diff(activation, axis=0)).max(axis=1) < 0.01) & (activation[1:].max(axis=1) > 0.1)
    change = np.diff(series, axis=0)
    return {
        "ratio_vertex": sums["v_err"] / max(sums["v_size"], 1e-300),
        "ratio_space": sums["s_err"] / max(sums["s_size"], 1e-300),
        "invented_flat_mm": sums["flat"] / max(sums["flat_n"], 1),
        "invented_marks_mm": sums["marks"] / max(sums["marks_n"], 1),
        "frame_change_rms_mm": float(np.sqrt(np.mean(change ** 2))) if len(series) > 1 else 0.0,
        "frame_change_held_rms_mm": float(np.sqrt(np.mean(change[held] ** 2))) if held.any() else float("nan"),
        "held_pairs": int(held.sum()),
        "frames": [int(t) for t in video],
    }


if __name__ == "__main__":
    import argparse
    import json

    p = argparse.ArgumentParser()
    p.add_argument("case")
    p.add_argument("base")
    p.add_argument("detail")
    a = p.parse_args()
    print(json.dumps(detail_metrics(Path(a.case), Path(a.base), Path(a.detail)), indent=1))
