"""build_anatomy on the bundled ICT face at a coarse setting: skin embedding, bone nodes, muscles, storage, picture."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree
from matplotlib import image as mpimg

from facecap.anatomy import (
    MUSCLE_NAMES,
    JAW_GAP_MM,
    build_anatomy,
    in_jaw_gap,
    is_mandible,
    jaw_joint,
    anatomy_landmarks,
    load_anatomy,
    render_anatomy_layout,
    tet_volumes,
)
from facecap.errors import FileFormatError, InputError
from facecap.synth import load_ict_sample


def test_skin_embedding_reproduces_every_scan_vertex(anatomy) -> None:
    scan = load_ict_sample().mesh.vertices
    assert anatomy.skin_tets.shape == (scan.shape[0],) and anatomy.skin_weights.shape == (scan.shape[0], 4)
    assert np.abs(anatomy.skin_positions() - scan).max() < 1e-9
    assert np.abs(anatomy.skin_matrix() @ anatomy.nodes - scan).max() < 1e-9
    assert np.allclose(anatomy.skin_weights.sum(axis=1), 1.0, atol=1e-12)
    # the skin moves with the mesh: a rigid motion of the nodes moves the skin rigidly
    c, s = np.cos(0.3), np.sin(0.3)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    moved = anatomy.skin_positions(anatomy.nodes @ R.T + [1.0, 2.0, 3.0])
    assert np.abs(moved - (scan @ R.T + [1.0, 2.0, 3.0])).max() < 1e-9
    # the meshed face region is the face in front of the ears, well inside the scan
    assert 0.5 < anatomy.skin_meshed.mean() < 0.9


def test_tetrahedra_are_positively_oriented(anatomy) -> None:
    assert anatomy.nodes.dtype == np.float64 and anatomy.tets.dtype == np.int64
    assert tet_volumes(anatomy.nodes, anatomy.tets).min() > 0
    assert anatomy.provenance["quality"]["n_inverted"] == 0


def test_bone_nodes_are_split_by_the_jaw_cut(anatomy) -> None:
    cran, mand = anatomy.cranium_nodes, anatomy.mandible_nodes
    assert cran.size > 50 and mand.size > 20
    assert np.intersect1d(cran, mand).size == 0 and np.intersect1d(cran, anatomy.rim_nodes).size == 0
    joint = jaw_joint(anatomy_landmarks(load_ict_sample().mesh))
    assert is_mandible(anatomy.nodes[mand], joint).all() and not is_mandible(anatomy.nodes[cran], joint).any()
    # Dirichlet nodes are on the bone surface: close to it, and at least the minimum tissue from the skin
    d_bone, _ = cKDTree(anatomy.bone_vertices).query(anatomy.nodes[np.concatenate([cran, mand])])
    assert np.median(d_bone) < 3.0
    d_skin, _ = cKDTree(anatomy.scan_vertices[anatomy.skin_meshed]).query(anatomy.nodes[cran])
    assert np.median(d_skin) > 3.0
    # the chin's bone is mandible, the forehead's is cranium
    p = dict(zip(anatomy.landmark_names, anatomy.landmark_points))
    _, near_chin = cKDTree(anatomy.nodes[np.concatenate([cran, mand])]).query(p["pogonion"] - [0, 0, 11.25])
    assert near_chin >= cran.size
    _, near_brow = cKDTree(anatomy.nodes[np.concatenate([cran, mand])]).query(p["glabella"] - [0, 0, 5.25])
    assert near_brow < cran.size


def test_the_bone_along_the_jaw_cut_holds_to_neither_jaw(anatomy) -> None:
    # Flesh glued to the cranium on one side of the cut and to the mandible a few mm away on the
    # other was crushed when the jaw moved (inverted elements at the mouth's corners on a 22k model):
    # no bone node within JAW_GAP_MM of the cut, measured here independently of in_jaw_gap
    joint = jaw_joint(anatomy_landmarks(load_ict_sample().mesh))
    bone = np.concatenate([anatomy.cranium_nodes, anatomy.mandible_nodes])
    local = (anatomy.nodes - joint.origin) @ joint.frame.T
    z, y = local[:, 2], local[:, 1]
    # the cut's occlusal segment, stomion backwards to the ramus front: vertical offset from it
    front = (z >= joint.cut_z[1]) & (z <= joint.cut_z[2])
    height = np.abs(y - np.interp(z, joint.cut_z, joint.cut_y))
    slope = np.diff(joint.cut_y[1:]) / np.diff(joint.cut_z[1:])
    across = height / np.sqrt(1.0 + slope[0] ** 2)  # distance to the straight segment
    assert np.all(across[bone][front[bone]] >= JAW_GAP_MM - 1e-9)
    # the band is real: boundary nodes on the bone there exist and are free (not rim, not bone)
    from facecap.anatomy.build_anatomy import boundary_nodes

    surface = boundary_nodes(anatomy.tets)
    in_band = surface[front[surface] & (across[surface] < JAW_GAP_MM)]
    d_bone, _ = cKDTree(anatomy.bone_vertices).query(anatomy.nodes[in_band])
    freed = in_band[d_bone < 1.0]
    assert freed.size >= 5
    assert np.intersect1d(freed, np.concatenate([bone, anatomy.rim_nodes])).size == 0
    assert in_jaw_gap(anatomy.nodes[freed], joint).all() and not in_jaw_gap(anatomy.nodes[bone], joint).any()
    assert anatomy.provenance["jaw_gap_mm"] == JAW_GAP_MM


def test_condyles_are_in_front_of_the_ears(anatomy) -> None:
    left, right = anatomy.condyles
    p = dict(zip(anatomy.landmark_names, anatomy.landmark_points))
    for c, side in ((left, "L"), (right, "R")):
        assert abs(c[0]) < abs(p[f"supraglenoid_{side}"][0])  # medial of the skin
        assert p[f"gonion_{side}"][1] < c[1] < p[f"supraorbital_{side}"][1]


def test_muscles_sit_between_their_origin_and_insertion(anatomy) -> None:
    assert anatomy.muscle_names == MUSCLE_NAMES and len(MUSCLE_NAMES) >= 30
    f, fib = anatomy.muscle_fractions, anatomy.muscle_fibres
    assert f.shape == (anatomy.n_tets, anatomy.n_muscles) and fib.shape == (anatomy.n_tets, anatomy.n_muscles, 3)
    assert f.min() >= 0.0 and f.max() <= 1.0
    used = f > 0
    assert np.allclose(np.linalg.norm(fib[used], axis=1), 1.0)
    assert np.all(fib[~used] == 0)
    centroids = anatomy.nodes[anatomy.tets].mean(axis=1)
    from scipy.spatial import cKDTree

    tree = cKDTree(centroids)
    for k, name in enumerate(anatomy.muscle_names):
        curve = anatomy.muscle_curves[k]
        assert used[:, k].sum() > 0, name
        # nonzero near the origin and the insertion (within the tube plus a tetrahedron's reach)
        reach = 0.5 * max(anatomy.muscle_widths_mm[k], anatomy.muscle_thicknesses_mm[k]) + 8.0
        for end in (curve[0], curve[-1]):
            near = tree.query_ball_point(end, reach)
            assert f[near, k].max() > 0, name
        # zero far from the centre curve
        d, _ = cKDTree(curve).query(centroids)
        assert np.all(f[d > reach + 6.0, k] == 0), name
    # straight muscles: the fibres follow the origin-to-insertion direction
    for name in ("zygomaticus_major_L", "zygomaticus_major_R", "frontalis_L", "risorius_R", "depressor_anguli_oris_L"):
        k = anatomy.muscle_names.index(name)
        c = anatomy.muscle_curves[k]
        axis = (c[-1] - c[0]) / np.linalg.norm(c[-1] - c[0])
        weights = f[:, k]
        mean_cos = float((weights * (fib[:, k] @ axis)).sum() / weights.sum())
        assert mean_cos > 0.9, name
    # rings: fibres run round the ring, across the direction to its centre
    k = anatomy.muscle_names.index("orbicularis_oris")
    centre = anatomy.muscle_curves[k].mean(axis=0)
    inside = used[:, k]
    radial = centroids[inside] - centre
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    assert np.median(np.abs(np.einsum("ij,ij->i", radial, fib[inside, k]))) < 0.4


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


def test_layout_picture(anatomy, tmp_path: Path) -> None:
    path = tmp_path / "layout.png"
    render_anatomy_layout(anatomy, path, size_px=(900, 500))
    img = mpimg.imread(path)
    assert img.shape[:2] == (500, 900)
    rgb = img[..., :3]
    # the muscles are coloured (saturated pixels), the skin grey, the background white
    saturation = rgb.max(axis=2) - rgb.min(axis=2)
    assert (saturation > 0.25).mean() > 0.02
    assert (rgb.min(axis=2) > 0.98).mean() > 0.2
    with pytest.raises(InputError, match="size_px"):
        render_anatomy_layout(anatomy, path, size_px=(10, 10))


def test_bad_input_is_refused() -> None:
    with pytest.raises(InputError, match="n_tets"):
        build_anatomy(load_ict_sample().mesh, n_tets=5, progress=False)
    with pytest.raises(InputError, match="Mesh"):
        build_anatomy(np.zeros((3, 3)), progress=False)


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
