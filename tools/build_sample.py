"""Build the bundled sample in ``src/facecap/data/`` from ``../shared/data`` (run once by developers).

Usage::

    python tools/build_sample.py [--shared ../shared/data]

Writes ``ict_face_sample.npz`` (the ICT-FaceKit face region in mm, its 53
expression deltas, 8 identity deltas and per-vertex face regions) and copies
the AnimFace take and its map. The licence notices live in
``src/facecap/data/README.md``.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import numpy as np

from facecap.io import read_mesh

FACE_VERTICES = 9409  # ICT "face (full face area)": vertices 0-9408
FACE_POLYGONS = 9230  # polygons 0-9229
N_IDENTITIES = 8
CM_TO_MM = 10.0

# dlib-68 landmark order used by ICT's idx_to_landmark_verts
LANDMARK_GROUPS = {
    "jaw": range(0, 17),
    "brows": range(17, 27),
    "nose": range(27, 36),
    "eyes": range(36, 48),
    "mouth": range(48, 68),
}
REGION_NAMES = ("forehead", "brows", "eyes", "nose", "cheeks", "mouth", "jaw")


def face_regions(V: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
    """Label each vertex with a face region from the 68 ICT landmarks.

    A vertex takes the group of its nearest landmark (brows, eyes, nose,
    mouth, jaw); vertices above the brows (by more than 8 mm) are forehead, and
    vertices farther than 18 mm from every landmark below the brows are cheeks.
    """
    L = V[landmarks]
    group_of_landmark = np.empty(68, dtype=np.int64)
    for name, idx in LANDMARK_GROUPS.items():
        group_of_landmark[list(idx)] = REGION_NAMES.index("jaw" if name == "jaw" else name)
    d = np.linalg.norm(V[:, None] - L[None], axis=2)
    nearest = d.argmin(axis=1)
    labels = group_of_landmark[nearest]
    brow_top = L[list(LANDMARK_GROUPS["brows"]), 1].max()
    labels[V[:, 1] > brow_top + 8.0] = REGION_NAMES.index("forehead")
    far = (d.min(axis=1) > 18.0) & (V[:, 1] <= brow_top + 8.0)
    labels[far] = REGION_NAMES.index("cheeks")
    return labels


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shared", default=str(Path(__file__).resolve().parents[2] / "shared" / "data"))
    args = parser.parse_args()
    shared = Path(args.shared)
    out = Path(__file__).resolve().parents[1] / "src" / "facecap" / "data"
    out.mkdir(parents=True, exist_ok=True)

    mesh = read_mesh(shared / "ict_face" / "generic_neutral_mesh.obj", unit="cm")
    sizes = mesh.polygon_sizes[:FACE_POLYGONS]
    corners = int(sizes.sum())
    polygon_indices = mesh.polygon_indices[:corners]
    triangles = mesh.faces[: int((sizes - 2).sum())]
    if polygon_indices.max() >= FACE_VERTICES or triangles.max() >= FACE_VERTICES:
        raise SystemExit("face polygons reference vertices outside the face region")
    uv_indices = mesh.uv_indices[:corners]
    used_uvs, uv_indices = np.unique(uv_indices, return_inverse=True)
    V = mesh.vertices[:FACE_VERTICES]

    expressions = np.load(shared / "ict_face" / "expressions.npz")
    neutral = expressions["neutral"][:FACE_VERTICES].astype(np.float64) * CM_TO_MM
    if np.abs(neutral - V).max() > 1e-3:
        raise SystemExit("expressions.npz neutral does not match the OBJ")
    deltas = (expressions["shapes"][:, :FACE_VERTICES] - expressions["neutral"][:FACE_VERTICES]) * CM_TO_MM
    identities = np.load(shared / "ict_face" / "identities.npz")
    id_deltas = (identities["shapes"][:N_IDENTITIES, :FACE_VERTICES] - identities["neutral"][:FACE_VERTICES]) * CM_TO_MM
    landmarks = np.array(json.loads((shared / "ict_face" / "vertex_indices.json").read_text())["idx_to_landmark_verts"])
    regions = face_regions(V, landmarks)

    np.savez_compressed(
        out / "ict_face_sample.npz",
        neutral=V.astype(np.float32),
        triangles=triangles.astype(np.int32),
        polygon_sizes=sizes.astype(np.int8),
        polygon_indices=polygon_indices.astype(np.int32),
        uvs=mesh.uvs[used_uvs].astype(np.float32),
        uv_indices=uv_indices.astype(np.int32),
        expression_deltas=deltas.astype(np.float32),
        expression_names=np.array([str(s) for s in expressions["names"]]),
        identity_deltas=id_deltas.astype(np.float32),
        landmarks=landmarks.astype(np.int32),
        region_labels=regions.astype(np.int8),
        region_names=np.array(REGION_NAMES),
    )
    shutil.copyfile(shared / "animface" / "eyebrows.c3d", out / "eyebrows.c3d")
    shutil.copyfile(shared / "animface" / "ict_generic_map.json", out / "ict_generic_map.json")
    shutil.copyfile(shared / "ict_face" / "LICENSE", out / "LICENSE-ICT-FaceKit.txt")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
