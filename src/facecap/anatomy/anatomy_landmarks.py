"""Named anatomical landmarks on the skin of a scan, and the face frame they define.

The anatomy is built from a small set of named skin points (glabella, pogonion,
the mouth corners, ...). They come either from a JSON file (name -> vertex
index or ``[x, y, z]`` point) or from the 68 iBUG/dlib facial landmarks, which
the ICT-FaceKit topology carries (``facecap.io.load_ict_sample().landmarks``).
The named points are built from the 68 by the fixed rules of
:data:`_CONSTRUCTION` (documented in ``docs/anatomy.md``) and snapped to the
nearest scan vertex, so every landmark is a vertex of the skin.
"""

from __future__ import annotations

import json
import os
from typing import Any, NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from ..errors import FileFormatError, InputError
from ..structures import Mesh
from ..typing import FloatArray, IntArray

__all__ = [
    "ANATOMY_LANDMARK_NAMES",
    "AnatomyLandmarks",
    "anatomy_landmarks",
    "face_frame",
    "landmarks_from_ibug68",
    "read_landmarks",
]

MAX_SNAP_DISTANCE_MM = 10.0
"""A landmark point further than this from every scan vertex is refused (it is not on this scan)."""

_MIDLINE = (
    "supraglabella", "glabella", "nasion", "rhinion", "pronasale", "subnasale", "mid_philtrum",
    "labrale_superius", "stomion", "labrale_inferius", "supramentale", "pogonion", "menton",
    "mid_forehead",
)
_BILATERAL = (
    "frontal_eminence", "supraorbital", "brow_inner", "brow_outer", "exocanthion", "endocanthion",
    "suborbital", "lateral_orbit", "zygomatic", "zygomatic_arch", "supraglenoid", "temple",
    "alare", "cheilion", "supra_m2", "occlusal_line", "sub_m2", "gonion", "mandible_border",
)
ANATOMY_LANDMARK_NAMES: tuple[str, ...] = _MIDLINE + tuple(
    f"{name}_{side}" for name in _BILATERAL for side in ("L", "R")
)
"""Every named landmark the anatomy uses; ``_L`` is the subject's left."""


class AnatomyLandmarks(NamedTuple):
    """Named skin landmarks of one scan and the face frame.

    Attributes
    ----------
    names : tuple of str
        :data:`ANATOMY_LANDMARK_NAMES`, in that order.
    vertices : (k,) int64 array
        The scan vertex each landmark sits on.
    points : (k, 3) float64 array, mm
        Their positions (the scan's vertices).
    frame : (3, 3) float64 array
        Rows: the subject's left (x), up (y) and forward (z, out of the face)
        unit vectors in scan coordinates, a right-handed orthonormal frame.
    origin : (3,) float64 array, mm
        The frame origin (the nasion).
    """

    names: tuple[str, ...]
    vertices: IntArray
    points: FloatArray
    frame: FloatArray
    origin: FloatArray

    def point(self, name: str) -> FloatArray:
        """Position of one named landmark, mm (raises InputError for an unknown name)."""
        return self.points[self.index(name)]

    def index(self, name: str) -> int:
        """Row of one named landmark."""
        try:
            return self.names.index(name)
        except ValueError:
            raise InputError(f"landmark: unknown name {name!r}") from None

    def local(self, P: Any) -> FloatArray:
        """Points in the face frame (x left, y up, z forward; mm from the nasion)."""
        return (np.asarray(P, dtype=np.float64) - self.origin) @ self.frame.T

    def as_dict(self) -> dict[str, int]:
        """``{name: vertex index}``, the JSON form that :func:`read_landmarks` reads back."""
        return {n: int(v) for n, v in zip(self.names, self.vertices)}


def _frame_from(points68: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Left, up, forward unit rows from the eye centres and the nasion-chin line."""
    P = points68
    left = P[42:48].mean(axis=0) - P[36:42].mean(axis=0)
    x = left / np.linalg.norm(left)
    up = P[27] - P[8]
    y = up - (up @ x) * x
    y /= np.linalg.norm(y)
    z = np.cross(x, y)
    return np.stack([x, y, z]), P[27].copy()


def _contour_at_height(local68: FloatArray, y: float, side: str) -> FloatArray:
    """The jaw contour (iBUG 0-8 or 8-16) interpolated at face-frame height y."""
    idx = np.arange(0, 9) if side == "R" else np.arange(16, 7, -1)
    C = local68[idx]
    order = np.argsort(C[:, 1])
    ys = C[order, 1]
    return np.array([np.interp(y, ys, C[order, k]) for k in range(3)])


def _construct(local68: FloatArray) -> dict[str, FloatArray]:
    """Named landmark positions in the face frame from the 68 points (before snapping).

    The rules (mm in the face frame: x left, y up, z forward) are listed in
    ``docs/anatomy.md``; they place each point where the forensic tissue-depth
    tables and anatomy texts put it relative to the eyes, brows, nose and mouth.
    """
    P = local68
    up = np.array([0.0, 1.0, 0.0])
    out: dict[str, FloatArray] = {}
    glabella = 0.5 * (P[21] + P[22])
    out["glabella"] = glabella
    out["supraglabella"] = glabella + 12.0 * up
    out["mid_forehead"] = glabella + 35.0 * up
    out["nasion"] = P[27]
    out["rhinion"] = 0.5 * (P[28] + P[29])
    out["pronasale"] = P[30]
    out["subnasale"] = P[33]
    out["mid_philtrum"] = 0.5 * (P[33] + P[51])
    out["labrale_superius"] = P[51]
    out["stomion"] = 0.5 * (P[62] + P[66])
    out["labrale_inferius"] = P[57]
    out["supramentale"] = P[57] + 0.40 * (P[8] - P[57])
    out["pogonion"] = P[57] + 0.72 * (P[8] - P[57])
    out["menton"] = P[8]
    stomion_y = out["stomion"][1]
    sides = {
        # side: (brow inner, brow mid, brow outer, eye ring, outer corner, inner corner,
        #        nostril base, mouth corner, lateral sign)
        "L": (22, 24, 26, slice(42, 48), 45, 42, 35, 54, 1.0),
        "R": (21, 19, 17, slice(36, 42), 36, 39, 31, 48, -1.0),
    }
    for side, (bi, bm, bo, eye, outer, inner, ala, corner, sign) in sides.items():
        lateral = np.array([sign, 0.0, 0.0])
        eye_centre = P[eye].mean(axis=0)
        out[f"brow_inner_{side}"] = P[bi]
        out[f"brow_outer_{side}"] = P[bo]
        out[f"supraorbital_{side}"] = P[bm]
        out[f"frontal_eminence_{side}"] = P[bm] + 30.0 * up
        out[f"exocanthion_{side}"] = P[outer]
        out[f"endocanthion_{side}"] = P[inner]
        out[f"suborbital_{side}"] = eye_centre - 12.0 * up
        out[f"lateral_orbit_{side}"] = P[outer] + 9.0 * lateral
        out[f"zygomatic_{side}"] = P[outer] + 3.0 * lateral - 26.0 * up
        orbitale_y = out[f"suborbital_{side}"][1]
        ear_front = _contour_at_height(P, orbitale_y, side)
        out[f"supraglenoid_{side}"] = ear_front + 8.0 * up
        out[f"zygomatic_arch_{side}"] = 0.4 * out[f"lateral_orbit_{side}"] + 0.6 * ear_front
        out[f"temple_{side}"] = 0.5 * (P[bo] + ear_front) + 22.0 * up
        out[f"alare_{side}"] = P[ala]
        out[f"cheilion_{side}"] = P[corner]
        occlusal = P[corner] + 0.55 * (_contour_at_height(P, stomion_y, side) - P[corner])
        out[f"occlusal_line_{side}"] = occlusal
        out[f"supra_m2_{side}"] = occlusal + 12.0 * up
        out[f"sub_m2_{side}"] = occlusal - 12.0 * up
        jaw = (3, 4) if side == "R" else (13, 12)
        out[f"gonion_{side}"] = 0.5 * (P[jaw[0]] + P[jaw[1]])
        out[f"mandible_border_{side}"] = P[6] if side == "R" else P[10]
    return out


def _snap(V: FloatArray, points: FloatArray, names: list[str], *, source: str, check: bool = True) -> IntArray:
    """Nearest scan vertex of each point; refuse given points far from the scan.

    Points built by the rules (``check=False``) may lie a little off the
    curved skin (a fixed offset up the forehead), so only given points are checked.
    """
    dist, idx = cKDTree(V).query(points)
    far = np.flatnonzero(dist > MAX_SNAP_DISTANCE_MM) if check else np.zeros(0, dtype=np.int64)
    if far.size:
        bad = ", ".join(f"{names[i]} ({dist[i]:.1f} mm)" for i in far[:5])
        raise InputError(
            f"landmarks lie further than {MAX_SNAP_DISTANCE_MM:g} mm from the scan: {bad}", path=source or None
        )
    return idx.astype(np.int64)


def _finish(V: FloatArray, named_vertices: dict[str, int], frame: FloatArray, origin: FloatArray) -> AnatomyLandmarks:
    idx = np.array([named_vertices[n] for n in ANATOMY_LANDMARK_NAMES], dtype=np.int64)
    return AnatomyLandmarks(ANATOMY_LANDMARK_NAMES, idx, V[idx].copy(), frame, origin)


def landmarks_from_ibug68(scan_mesh: Mesh, points68: Any, *, source: str = "") -> AnatomyLandmarks:
    """Named anatomical landmarks from the 68 iBUG/dlib facial landmarks.

    Parameters
    ----------
    scan_mesh : Mesh
        The skin (mm).
    points68 : (68,) int array of vertex indices, or (68, 3) float array, mm
        The 68 landmarks in iBUG order (0-16 jaw contour from the subject's
        right, 17-26 brows, 27-35 nose, 36-47 eyes, 48-67 mouth).
    source : str, optional
        File the landmarks came from, named in errors.

    Returns
    -------
    AnatomyLandmarks

    Raises
    ------
    InputError
        If ``points68`` has the wrong shape, indices out of range, or points
        further than 10 mm from the scan.
    """
    V = scan_mesh.vertices
    A = np.asarray(points68)
    if A.shape == (68,) and np.issubdtype(A.dtype, np.integer):
        if A.min() < 0 or A.max() >= V.shape[0]:
            raise InputError(f"ibug68: vertex indices must lie in [0, {V.shape[0]})", path=source or None)
        P = V[A.astype(np.int64)]
    elif A.shape == (68, 3):
        P = np.asarray(A, dtype=np.float64)
        if not np.all(np.isfinite(P)):
            raise InputError("ibug68: points contain NaN or infinite values", path=source or None)
    else:
        raise InputError(f"ibug68: expected 68 vertex indices or (68, 3) points, got shape {A.shape}", path=source or None)
    frame, origin = _frame_from(P)
    local = (P - origin) @ frame.T
    built = _construct(local)
    names = list(built)
    pts = np.array([built[n] for n in names]) @ frame + origin
    idx = _snap(V, pts, names, source=source, check=False)
    return _finish(V, dict(zip(names, idx.tolist())), frame, origin)


def _is_ict_topology(scan_mesh: Mesh) -> bool:
    from ..io.ict_sample import load_ict_sample

    sample = load_ict_sample().mesh
    n, m = sample.n_vertices, sample.faces.shape[0]
    return (
        scan_mesh.n_vertices >= n
        and scan_mesh.faces.shape[0] >= m
        and np.array_equal(scan_mesh.faces[:m], sample.faces)
    )


def read_landmarks(path: str | os.PathLike[str], scan_mesh: Mesh) -> AnatomyLandmarks:
    """Read a landmark JSON file for a scan.

    Parameters
    ----------
    path : str or path-like
        JSON object. Either every name of :data:`ANATOMY_LANDMARK_NAMES`
        mapped to a vertex index (int) or a point ``[x, y, z]`` in mm (snapped
        to the nearest vertex), or the key ``"ibug68"`` mapped to a list of
        68 such entries in iBUG order (the named points are then built from
        them). Unknown extra names are refused, so that a typo is not silently
        ignored.
    scan_mesh : Mesh
        The scan the indices refer to.

    Returns
    -------
    AnatomyLandmarks

    Raises
    ------
    FileFormatError
        If the file is missing or not a JSON object.
    InputError
        If names are missing or unknown, an index is out of range, or a point
        lies further than 10 mm from the scan.
    """
    src = os.fspath(path)
    try:
        with open(src, encoding="utf-8") as handle:
            data = json.load(handle)
    except FileNotFoundError:
        raise FileFormatError("landmark file not found", path=src) from None
    except (OSError, ValueError) as exc:
        raise FileFormatError(f"not a readable JSON file ({exc})", path=src) from None
    if not isinstance(data, dict):
        raise FileFormatError("expected a JSON object mapping landmark names to vertices or points", path=src)
    return _from_mapping(data, scan_mesh, src)


def _from_mapping(data: dict[str, Any], scan_mesh: Mesh, src: str) -> AnatomyLandmarks:
    """Named landmarks from a parsed mapping (see :func:`read_landmarks`); ``src`` names it in errors."""
    V = scan_mesh.vertices
    if "ibug68" in data:
        entries = data["ibug68"]
        if not isinstance(entries, list) or len(entries) != 68:
            raise InputError("ibug68: expected a list of 68 vertex indices or [x, y, z] points", path=src)
        P = np.array([_entry_point(V, e, f"ibug68[{i}]", src) for i, e in enumerate(entries)])
        return landmarks_from_ibug68(scan_mesh, P, source=src)
    unknown = sorted(set(data) - set(ANATOMY_LANDMARK_NAMES))
    if unknown:
        raise InputError(f"unknown landmark names {unknown[:5]}; expected {list(ANATOMY_LANDMARK_NAMES)[:4]} ...", path=src)
    missing = [n for n in ANATOMY_LANDMARK_NAMES if n not in data]
    if missing:
        raise InputError(f"missing landmarks {missing[:6]}{' ...' if len(missing) > 6 else ''} ({len(missing)} of {len(ANATOMY_LANDMARK_NAMES)})", path=src)
    pts = np.array([_entry_point(V, data[n], n, src) for n in ANATOMY_LANDMARK_NAMES])
    idx = _snap(V, pts, list(ANATOMY_LANDMARK_NAMES), source=src)
    frame_pts = {n: V[i] for n, i in zip(ANATOMY_LANDMARK_NAMES, idx)}
    frame = face_frame(frame_pts)
    return _finish(V, dict(zip(ANATOMY_LANDMARK_NAMES, idx.tolist())), frame, frame_pts["nasion"].copy())


def face_frame(points: dict[str, Any]) -> FloatArray:
    """The face frame from named landmarks: rows left, up, forward (unit, right-handed).

    Left: from the right eye corners' midpoint to the left's; up: from the
    menton toward the nasion, made orthogonal to left; forward = left x up.
    """
    p = {k: np.asarray(v, dtype=np.float64) for k, v in points.items()}
    x = p["exocanthion_L"] + p["endocanthion_L"] - p["exocanthion_R"] - p["endocanthion_R"]
    x = x / np.linalg.norm(x)
    up = p["nasion"] - p["menton"]
    y = up - (up @ x) * x
    y = y / np.linalg.norm(y)
    return np.stack([x, y, np.cross(x, y)])


def _entry_point(V: FloatArray, entry: Any, name: str, src: str) -> FloatArray:
    if isinstance(entry, bool):
        raise InputError(f"{name}: expected a vertex index or [x, y, z], got {entry!r}", path=src)
    if isinstance(entry, int):
        if not 0 <= entry < V.shape[0]:
            raise InputError(f"{name}: vertex {entry} out of range [0, {V.shape[0]})", path=src)
        return V[entry]
    A = np.asarray(entry, dtype=object)
    if A.shape != (3,) or not all(isinstance(a, (int, float)) and not isinstance(a, bool) for a in A):
        raise InputError(f"{name}: expected a vertex index or [x, y, z], got {entry!r}", path=src)
    P = np.asarray(entry, dtype=np.float64)
    if not np.all(np.isfinite(P)):
        raise InputError(f"{name}: point is not finite", path=src)
    return P


def anatomy_landmarks(scan_mesh: Mesh, landmarks: Any = None) -> AnatomyLandmarks:
    """The named landmarks of a scan: from a file, a mapping, or the ICT topology.

    Parameters
    ----------
    scan_mesh : Mesh
        The skin, mm.
    landmarks : str, path-like, dict, AnatomyLandmarks or None, optional
        A JSON file or an already parsed mapping (see :func:`read_landmarks`);
        None (default) works for scans in the ICT-FaceKit topology (the face
        region or the full head), whose 68 landmark vertices the package knows.

    Returns
    -------
    AnatomyLandmarks

    Raises
    ------
    InputError
        If ``landmarks`` is None and the scan is not in the ICT topology, or
        the landmarks are bad (see :func:`read_landmarks`).
    """
    if isinstance(landmarks, AnatomyLandmarks):
        return landmarks
    if landmarks is None:
        if not _is_ict_topology(scan_mesh):
            raise InputError(
                "landmarks: the scan is not in the ICT-FaceKit topology, so its landmarks are unknown; "
                "give a landmark JSON file (name -> vertex index or [x, y, z], or 'ibug68': [...])",
                path=scan_mesh.source_path,
            )
        from ..io.ict_sample import load_ict_sample

        return landmarks_from_ibug68(scan_mesh, load_ict_sample().landmarks)
    if isinstance(landmarks, dict):
        return _from_mapping(landmarks, scan_mesh, "")
    return read_landmarks(landmarks, scan_mesh)
