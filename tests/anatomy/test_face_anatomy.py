"""FaceAnatomy and load_anatomy: the saved model reads back array for array, with the scan's polygons and UVs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from facecap.anatomy import load_anatomy
from facecap.errors import FileFormatError
from facecap.io.ict_sample import load_ict_sample


def test_save_and_load_round_trip(anatomy, tmp_path: Path) -> None:
    folder = anatomy.save(tmp_path / "model")
    meta = json.loads((folder / "anatomy.json").read_text())
    assert meta["units"] == "mm" and meta["counts"]["tets"] == anatomy.n_tets
    assert not list(folder.glob(".*partial*"))
    again = load_anatomy(folder)
    for name in ("nodes", "tets", "muscle_fractions", "muscle_fibres", "cranium_nodes", "mandible_nodes",
                 "skin_tets", "skin_weights", "condyles", "muscle_curves", "bone_vertices", "scan_faces"):
        a, b = getattr(anatomy, name), getattr(again, name)
        assert a.dtype == b.dtype and np.array_equal(a, b), name
    assert again.muscle_names == anatomy.muscle_names and again.landmark_names == anatomy.landmark_names
    assert again.provenance["quality"] == anatomy.provenance["quality"]
    (folder / "anatomy.json").write_text(json.dumps({**meta, "format": "other/9"}))
    with pytest.raises(FileFormatError, match="format"):
        load_anatomy(folder)
    with pytest.raises(FileFormatError, match="missing"):
        load_anatomy(tmp_path / "nothing")


def test_the_model_keeps_the_scans_polygons_and_uvs_for_the_exports(anatomy, tmp_path) -> None:
    scan = load_ict_sample().mesh
    mesh = anatomy.scan_mesh()
    np.testing.assert_array_equal(mesh.polygon_sizes, scan.polygon_sizes)
    np.testing.assert_array_equal(mesh.polygon_indices, scan.polygon_indices)
    np.testing.assert_array_equal(mesh.uvs, scan.uvs)
    np.testing.assert_array_equal(mesh.uv_indices, scan.uv_indices)
    np.testing.assert_array_equal(mesh.vertices, scan.vertices)
    loaded = load_anatomy(anatomy.save(tmp_path / "model")).scan_mesh()
    np.testing.assert_array_equal(loaded.polygon_indices, scan.polygon_indices)
    np.testing.assert_array_equal(loaded.uv_indices, scan.uv_indices)
    # a model saved before the polygons and UVs were kept still loads: triangles, no UVs
    with np.load(tmp_path / "model" / "anatomy.npz") as data:
        older = {name: data[name] for name in data.files if not name.startswith(("scan_polygon", "scan_uv"))}
    np.savez(tmp_path / "model" / "anatomy.npz", **older)
    old = load_anatomy(tmp_path / "model").scan_mesh()
    assert old.uvs is None and old.polygon_sizes is None and np.array_equal(old.faces, anatomy.scan_faces)
    # polygons whose corners do not add up are a broken file, named
    np.savez(tmp_path / "model" / "anatomy.npz", **older, scan_polygon_sizes=scan.polygon_sizes,
             scan_polygon_indices=scan.polygon_indices[:-1])
    with pytest.raises(FileFormatError, match="anatomy.npz"):
        load_anatomy(tmp_path / "model")
