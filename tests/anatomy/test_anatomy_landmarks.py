"""anatomy_landmarks and read_landmarks: the ICT landmarks, the JSON file and the 68 iBUG points agree; bad input refused."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from anatomy_meshes import grid_mesh as _grid_mesh
from facecap.anatomy import ANATOMY_LANDMARK_NAMES, anatomy_landmarks, read_landmarks
from facecap.errors import FileFormatError, InputError
from facecap.io.ict_sample import load_ict_sample


def test_landmark_json_round_trip_and_errors(tmp_path: Path) -> None:
    mesh = load_ict_sample().mesh
    lm = anatomy_landmarks(mesh)
    assert lm.names == ANATOMY_LANDMARK_NAMES
    path = tmp_path / "landmarks.json"
    path.write_text(json.dumps(lm.as_dict()))
    again = read_landmarks(path, mesh)
    assert np.array_equal(again.vertices, lm.vertices)
    # points a little off the surface snap to the nearest vertex (0.09 mm off; vertices are >= 0.3 mm apart at the mouth corners)
    moved = {n: (mesh.vertices[v] + 0.05).tolist() for n, v in lm.as_dict().items()}
    path.write_text(json.dumps(moved))
    assert np.array_equal(read_landmarks(path, mesh).vertices, lm.vertices)
    # the 68 iBUG points give the same named landmarks as the built-in ICT ones
    path.write_text(json.dumps({"ibug68": load_ict_sample().landmarks.tolist()}))
    assert np.array_equal(read_landmarks(path, mesh).vertices, lm.vertices)
    bad = dict(lm.as_dict())
    del bad["pogonion"]
    path.write_text(json.dumps(bad))
    with pytest.raises(InputError, match="missing landmarks.*pogonion"):
        read_landmarks(path, mesh)
    far = dict(moved)
    far["menton"] = [0.0, -75.7, 160.0]
    path.write_text(json.dumps(far))
    with pytest.raises(InputError, match="menton"):
        read_landmarks(path, mesh)
    path.write_text("[1, 2")
    with pytest.raises(FileFormatError):
        read_landmarks(path, mesh)
    with pytest.raises(FileFormatError, match="not found"):
        read_landmarks(tmp_path / "none.json", mesh)


def test_a_scan_outside_the_ict_topology_needs_landmarks() -> None:
    V, F = _grid_mesh(6)
    from facecap.structures import Mesh

    with pytest.raises(InputError, match="not in the ICT-FaceKit topology"):
        anatomy_landmarks(Mesh(vertices=V, faces=F))


def test_a_scan_too_small_for_its_landmarks_is_refused() -> None:
    from facecap.structures import Mesh

    full = load_ict_sample().mesh
    lm = anatomy_landmarks(full)
    # only the nose of the face: the landmarks (as points) lie far from it
    nose = np.flatnonzero(np.linalg.norm(full.vertices - lm.point("pronasale"), axis=1) < 20)
    keep = np.isin(full.faces, nose).all(axis=1)
    used, inverse = np.unique(full.faces[keep], return_inverse=True)
    small = Mesh(vertices=full.vertices[used], faces=inverse.reshape(-1, 3))
    with pytest.raises(InputError, match="further than 10 mm"):
        anatomy_landmarks(small, {n: p.tolist() for n, p in zip(lm.names, lm.points)})
