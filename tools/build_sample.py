"""Build the bundled ICT face sample in ``src/facecap/data/`` (run once by developers).

Reads the ICT-FaceKit model and the AnimFace take from a local copy of the
source data (default ``/work/shared/data``) and writes:

- ``src/facecap/data/ict_face_sample.npz``: the FACE REGION of the ICT generic
  neutral (vertices 0-9408, polygons 0-9229 of ``generic_neutral_mesh.obj``),
  in millimetres, with its quads, fan triangles, UVs, the 53 expression deltas,
  the first identity deltas, the 68 ICT landmarks and per-vertex region labels;
- ``src/facecap/data/eyebrows.c3d`` and ``ict_generic_map.json``: copied as they are;
- ``src/facecap/data/LICENSE-ICT-FaceKit.txt``: the ICT-FaceKit licence, copied (the
  hand-written ``README.md`` beside it must reproduce it; the script checks).

Usage::

    python tools/build_sample.py [--source /work/shared/data] [--n-identities 8]

The package never reads the source data at run time; tests read only the
bundled files. Region labels are derived geometrically from the neutral and the
ICT 68 landmarks (see :func:`region_labels`), and ``docs/synthetic_data.md``
documents the rules.
"""

from __future__ import annotations

import argparse
import itertools
import json
import shutil
from pathlib import Path

import numpy as np

FACE_VERTICES = 9409
"""Vertices 0-9408 are the ICT face region."""
FACE_POLYGONS = 9230
"""Polygons 0-9229 (the first 9230 ``f`` lines) are the ICT face region."""
NARROW_FACE_VERTICES = 6706
"""Vertices 0-6705 are the ICT 'narrow face area' (the front of the face)."""
MM_PER_CM = 10.0

REGION_NAMES = ("forehead", "brows", "eyes", "nose", "cheeks", "mouth", "chin_jaw", "other")

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "src" / "facecap" / "data"


def read_obj_face_region(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Read positions, polygons and UVs of the face region of an OBJ.

    Returns ``(V_cm, sizes, indices, uvs, uv_indices)`` with 0-based indices;
    the UVs are compacted to those the face polygons use.
    """
    V: list[list[float]] = []
    VT: list[list[float]] = []
    polys: list[list[tuple[int, int]]] = []
    with open(path, encoding="utf-8") as fh:
        for line in fh:
            if line.startswith("v "):
                V.append([float(x) for x in line.split()[1:4]])
            elif line.startswith("vt "):
                VT.append([float(x) for x in line.split()[1:3]])
            elif line.startswith("f ") and len(polys) < FACE_POLYGONS:
                corners = []
                for c in line.split()[1:]:
                    parts = c.split("/")
                    corners.append((int(parts[0]) - 1, int(parts[1]) - 1))
                polys.append(corners)
    sizes = np.array([len(p) for p in polys], dtype=np.int64)
    idx = np.array([c[0] for p in polys for c in p], dtype=np.int64)
    tidx = np.array([c[1] for p in polys for c in p], dtype=np.int64)
    if idx.max() >= FACE_VERTICES:
        raise SystemExit(f"{path}: face polygons reference vertex {idx.max()} >= {FACE_VERTICES}")
    used, uv_indices = np.unique(tidx, return_inverse=True)
    uvs = np.asarray(VT, dtype=np.float64)[used]
    return np.asarray(V, dtype=np.float64)[:FACE_VERTICES], sizes, idx, uvs, uv_indices.astype(np.int64)


def fan_triangles(sizes: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Fan-triangulate polygons: corner 0 with each pair (j, j+1), in polygon order."""
    tris = []
    start = 0
    for s in sizes:
        p = indices[start : start + s]
        for j in range(1, s - 1):
            tris.append((p[0], p[j], p[j + 1]))
        start += s
    return np.asarray(tris, dtype=np.int64)


def region_labels(V: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
    """Per-vertex region label (index into REGION_NAMES), from the neutral (mm) and 68 landmarks.

    Rules, in the frontal (x, y) projection (x: subject's left, y: up), first match wins:

    1. other: outside the ICT narrow face area (vertex >= 6706: ears, scalp, sides, neck);
    2. eyes: inside an ellipse per eye centred on landmarks 36-41 / 42-47, semi-axes
       half the eye width + 6 mm and 12 mm (lids included);
    3. brows: within 10 mm of the brow polylines (landmarks 17-21 / 22-26);
    4. mouth: inside an ellipse centred on the outer lip landmarks 48-59, semi-axes
       half the mouth width + 7 mm and half the lip height + 7 mm;
    5. nose: between 4 mm below the subnasale (33) and 6 mm above the nasion (27), within a
       half-width growing linearly from 10 mm at the top to the alar half-width + 10 mm at the bottom;
    6. forehead: above the brow line (brow landmarks' height interpolated in x, held
       flat beyond the ends), or above the nose and between the inner brow ends (glabella);
    7. chin_jaw: below the mouth corners' height minus 5 mm;
    8. cheeks: the rest (cheeks, temples below the brow line, nasolabial area).
    """
    x, y = V[:, 0], V[:, 1]
    L = V[landmarks]
    lab = np.full(V.shape[0], -1, dtype=np.int64)
    free = np.ones(V.shape[0], dtype=bool)
    free[NARROW_FACE_VERTICES:] = False
    lab[~free] = REGION_NAMES.index("other")

    def claim(mask: np.ndarray, name: str) -> None:
        m = mask & free
        lab[m] = REGION_NAMES.index(name)
        free[m] = False

    eyes = np.zeros(V.shape[0], dtype=bool)
    for sl in (slice(36, 42), slice(42, 48)):
        P = L[sl]
        c = P.mean(axis=0)
        a = 0.5 * (P[:, 0].max() - P[:, 0].min()) + 6.0
        eyes |= ((x - c[0]) / a) ** 2 + ((y - c[1]) / 12.0) ** 2 <= 1.0
    claim(eyes, "eyes")

    brows = np.zeros(V.shape[0], dtype=bool)
    for sl in (slice(17, 22), slice(22, 27)):
        P = L[sl, :2]
        for p, q in itertools.pairwise(P):
            d = q - p
            t = np.clip(((np.c_[x, y] - p) @ d) / (d @ d), 0.0, 1.0)
            dist = np.linalg.norm(np.c_[x, y] - (p + t[:, None] * d), axis=1)
            brows |= dist <= 10.0
    claim(brows, "brows")

    P = L[48:60]
    c = P.mean(axis=0)
    a = 0.5 * (P[:, 0].max() - P[:, 0].min()) + 7.0
    b = 0.5 * (P[:, 1].max() - P[:, 1].min()) + 7.0
    claim(((x - c[0]) / a) ** 2 + ((y - c[1]) / b) ** 2 <= 1.0, "mouth")

    top, bottom = L[27, 1] + 6.0, L[33, 1] - 4.0
    alar = 0.5 * abs(L[35, 0] - L[31, 0]) + 10.0
    s = np.clip((top - y) / (top - bottom), 0.0, 1.0)
    half = 10.0 + s * (alar - 10.0)
    claim((y <= top) & (y >= bottom) & (np.abs(x) <= half), "nose")

    B = L[17:27]
    order = np.argsort(B[:, 0])
    brow_y = np.interp(x, B[order, 0], B[order, 1])
    glabella = (y > top) & (np.abs(x) <= abs(L[21, 0]))
    claim((y > brow_y) | glabella, "forehead")
    claim(y < min(L[48, 1], L[54, 1]) - 5.0, "chin_jaw")
    claim(np.ones(V.shape[0], dtype=bool), "cheeks")
    return lab


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--source", type=Path, default=Path("/work/shared/data"))
    ap.add_argument("--n-identities", type=int, default=8)
    args = ap.parse_args()
    ict = args.source / "ict_face"
    anim = args.source / "animface"

    V_cm, sizes, indices, uvs, uv_indices = read_obj_face_region(ict / "generic_neutral_mesh.obj")
    expr = np.load(ict / "expressions.npz")
    ident = np.load(ict / "identities.npz")
    neutral_cm = expr["neutral"][:FACE_VERTICES].astype(np.float64)
    # The OBJ and the npz neutral are the same positions (float32 vs text rounding).
    err = np.abs(neutral_cm - V_cm).max()
    if err > 1e-5:
        raise SystemExit(f"OBJ and expressions.npz neutral differ by {err} cm")
    if np.abs(ident["neutral"].astype(np.float64) - expr["neutral"]).max() > 0:
        raise SystemExit("identities.npz and expressions.npz have different neutrals")

    neutral = neutral_cm * MM_PER_CM
    deltas64 = (expr["shapes"][:, :FACE_VERTICES].astype(np.float64) - neutral_cm) * MM_PER_CM
    deltas = deltas64.astype(np.float32)
    k = args.n_identities
    id64 = (ident["shapes"][:k, :FACE_VERTICES].astype(np.float64) - neutral_cm) * MM_PER_CM
    id32 = id64.astype(np.float32)
    loss = max(np.abs(deltas.astype(np.float64) - deltas64).max(), np.abs(id32.astype(np.float64) - id64).max())
    if loss >= 0.01:
        raise SystemExit(f"float32 storage loses {loss} mm (limit 0.01 mm)")

    idx = json.loads((ict / "vertex_indices.json").read_text())
    landmarks = np.asarray(idx["idx_to_landmark_verts"], dtype=np.int64)
    if landmarks.max() >= FACE_VERTICES:
        raise SystemExit("a landmark lies outside the face region")
    labels = region_labels(neutral, landmarks)

    OUT.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        OUT / "ict_face_sample.npz",
        neutral=neutral,
        polygon_sizes=sizes,
        polygon_indices=indices,
        triangles=fan_triangles(sizes, indices),
        uvs=uvs,
        uv_indices=uv_indices,
        expression_deltas=deltas,
        expression_names=np.asarray(expr["names"]).astype(str),
        identity_deltas=id32,
        identity_names=np.asarray(ident["names"][:k]).astype(str),
        landmarks=landmarks,
        region_labels=labels,
        region_names=np.asarray(REGION_NAMES),
        narrow_face_vertices=np.int64(NARROW_FACE_VERTICES),
    )
    for name in ("eyebrows.c3d", "ict_generic_map.json"):
        shutil.copyfile(anim / name, OUT / name)
    shutil.copyfile(ict / "LICENSE", OUT / "LICENSE-ICT-FaceKit.txt")
    readme = OUT / "README.md"
    licence = (ict / "LICENSE").read_text(encoding="utf-8").strip()
    if not readme.is_file() or licence not in readme.read_text(encoding="utf-8"):
        raise SystemExit(f"{readme}: must reproduce the ICT-FaceKit licence text verbatim")
    mp = json.loads((OUT / "ict_generic_map.json").read_text())
    if max(mp.values()) >= FACE_VERTICES:
        raise SystemExit("ict_generic_map.json names a vertex outside the face region")
    total = sum(p.stat().st_size for p in OUT.iterdir() if p.is_file())
    print(f"wrote {OUT} ({total / 1e6:.2f} MB); float32 loss {loss:.2e} mm")
    counts = np.bincount(labels, minlength=len(REGION_NAMES))
    print(dict(zip(REGION_NAMES, counts.tolist())))


if __name__ == "__main__":
    main()
