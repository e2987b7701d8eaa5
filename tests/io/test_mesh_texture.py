"""Textured meshes in and out: OBJ with MTL, PLY with TextureFile, glTF base colour; checked against trimesh."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh

from facecap.errors import FacecapWarning
from facecap.io import read_mesh, write_mesh
from facecap.io.image_file import write_image
from facecap.mesh import surface_colors, texel_size_mm
from facecap.structures import Mesh

_SQUARE_V = np.array([[0.0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0]])
_SQUARE_F = np.array([[0, 1, 2], [0, 2, 3]])
_SQUARE_UV = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]])


def _image(h: int, w: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (h, w, 3)).astype(np.uint8)


def _texel_centres(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """UVs of every texel centre and the (row, col) each is, row 0 the image's top."""
    rows, cols = np.mgrid[0:h, 0:w]
    uv = np.stack([(cols.ravel() + 0.5) / w, 1.0 - (rows.ravel() + 0.5) / h], axis=1)
    return uv, np.stack([rows.ravel(), cols.ravel()], axis=1)


def _points_of_uv(uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangle and barycentric coordinates on the unit-UV square of the point at each UV."""
    upper = uv[:, 1] > uv[:, 0]  # triangle 1: corners (0,0), (1,1), (0,1)
    u, v = uv[:, 0], uv[:, 1]
    w0 = np.where(upper, 1 - v, 1 - u)
    w1 = np.where(upper, u, u - v)
    w2 = np.where(upper, v - u, v)
    return upper.astype(np.int64), np.stack([w0, w1, w2], axis=1)


@pytest.mark.parametrize("suffix", ["obj", "ply"])
def test_a_texture_round_trips_and_trimesh_reads_the_same_colours(tmp_path, suffix):
    image = _image(6, 9, seed=1)
    mesh = Mesh(_SQUARE_V, _SQUARE_F, uvs=_SQUARE_UV, uv_indices=_SQUARE_F.ravel(), texture=image)
    path = write_mesh(mesh, tmp_path / f"square.{suffix}")
    back = read_mesh(path)
    assert np.array_equal(back.texture, image)
    uv, rc = _texel_centres(6, 9)
    tri, bary = _points_of_uv(uv)
    # at texel centres the bilinear lookup is the texel itself
    ours = surface_colors(back, tri, bary)
    assert np.allclose(ours, image[rc[:, 0], rc[:, 1]] / 255.0, atol=1e-6)
    if suffix == "obj":  # the reference reader finds the same image through the MTL file
        theirs = trimesh.load(path, process=False)
        colours = trimesh.visual.color.uv_to_color(uv, theirs.visual.material.image)[:, :3]
        assert np.allclose(ours, colours / 255.0, atol=1e-6)
    assert texel_size_mm(back) == pytest.approx(10.0 / np.sqrt(6 * 9))


def test_sixteen_bit_textures_keep_their_depth(tmp_path):
    image = np.random.default_rng(2).integers(0, 65536, (4, 5, 3)).astype(np.uint16)
    mesh = Mesh(_SQUARE_V, _SQUARE_F, uvs=_SQUARE_UV, uv_indices=_SQUARE_F.ravel(), texture=image)
    back = read_mesh(write_mesh(mesh, tmp_path / "square.obj"))
    assert back.texture.dtype == np.uint16 and np.array_equal(back.texture, image)


def test_several_materials_are_packed_and_each_face_keeps_its_own_image(tmp_path):
    # two quads side by side, each with its own material and image; UVs both span [0, 1]
    left, right = _image(8, 8, seed=3), _image(5, 12, seed=4)
    write_image(tmp_path / "left.png", left)
    write_image(tmp_path / "Right.PNG", right)
    (tmp_path / "two.mtl").write_text(
        "newmtl a\nKd 1 1 1\nmap_Kd -o 0 0 0 left.png\n"
        "newmtl b\nmap_Kd textures\\right.png\n")  # a Windows path, another case: found by name
    (tmp_path / "two.obj").write_text(
        "mtllib none.mtl two.mtl\n"  # several files on one line, as the OBJ specification allows
        "v 0 0 0\nv 10 0 0\nv 10 10 0\nv 0 10 0\nv 20 0 0\nv 20 10 0\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "usemtl a\nf 1/1 2/2 3/3 4/4\nusemtl b\nf 2/1 5/2 6/3 3/4\n")
    with pytest.warns(FacecapWarning, match="-o/-s"):  # the offset option is named, not applied
        mesh = read_mesh(tmp_path / "two.obj")
    assert mesh.texture is not None
    uv, rc = _texel_centres(8, 8)
    tri, bary = _points_of_uv(uv)  # the first quad's triangles are 0 and 1
    assert np.allclose(surface_colors(mesh, tri, bary), left[rc[:, 0], rc[:, 1]] / 255.0, atol=1e-5)
    uv, rc = _texel_centres(5, 12)
    tri, bary = _points_of_uv(uv)
    assert np.allclose(surface_colors(mesh, tri + 2, bary), right[rc[:, 0], rc[:, 1]] / 255.0, atol=1e-5)


def test_a_missing_texture_costs_the_colour_not_the_mesh(tmp_path):
    (tmp_path / "m.mtl").write_text("newmtl skin\nmap_Kd nowhere.png\n")
    (tmp_path / "m.obj").write_text("mtllib m.mtl\nusemtl skin\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                    "f 1/1 2/2 3/3\n")
    with pytest.warns(FacecapWarning, match="nowhere.png"):
        mesh = read_mesh(tmp_path / "m.obj")
    assert mesh.texture is None and mesh.n_faces == 1 and mesh.uvs is not None
    (tmp_path / "n.obj").write_text("mtllib gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                    "f 1/1 2/2 3/3\n")
    with warnings.catch_warnings():  # a mesh copied without its MTL: read as geometry, silently
        warnings.simplefilter("error")
        assert read_mesh(tmp_path / "n.obj").texture is None


def test_an_obj_without_materials_reads_as_before(tmp_path):
    (tmp_path / "p.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert read_mesh(tmp_path / "p.obj").texture is None


def test_gltf_base_colour_textures_are_read_as_trimesh_reads_them(tmp_path):
    from PIL import Image

    image = _image(16, 16, seed=5)
    visual = trimesh.visual.TextureVisuals(uv=_SQUARE_UV, material=trimesh.visual.material.PBRMaterial(
        baseColorTexture=Image.fromarray(image)))
    square = trimesh.Trimesh(_SQUARE_V / 1000.0, _SQUARE_F, visual=visual, process=False)
    path = tmp_path / "square.glb"
    square.export(path)
    mesh = read_mesh(path)
    assert mesh.texture is not None
    uv, rc = _texel_centres(16, 16)
    tri, bary = _points_of_uv(uv)
    theirs = trimesh.load(path, process=False, force="mesh")
    reference = trimesh.visual.color.uv_to_color(uv, theirs.visual.material.baseColorTexture)[:, :3] / 255.0
    assert np.allclose(surface_colors(mesh, tri, bary), reference, atol=1e-6)


def test_a_textured_sequence_shares_one_image(tmp_path):
    from facecap.io import PerformanceWriter

    image = _image(4, 4, seed=6)
    mesh = Mesh(_SQUARE_V, _SQUARE_F, uvs=_SQUARE_UV, uv_indices=_SQUARE_F.ravel(), texture=image)
    frames = np.stack([_SQUARE_V + k for k in range(3)]).astype(np.float32)
    with PerformanceWriter(tmp_path / "result", mesh=mesh, rate=30.0, n_frames=3, exports=("obj", "ply")) as writer:
        writer.write_frames(0, frames)
        writer.finish({})
    for fmt in ("obj", "ply"):
        folder = tmp_path / "result" / fmt
        assert sorted(p.name for p in folder.glob("*.png")) == ["texture_color.png"]
        for k in range(3):
            back = read_mesh(folder / f"frame_{k:06d}.{fmt}")
            assert np.array_equal(back.texture, image) and np.allclose(back.vertices, frames[k])


def test_a_ply_with_several_textures_packs_them_by_texnumber(tmp_path):
    red = np.zeros((4, 4, 3), np.uint8)
    red[..., 0] = 255
    blue = np.zeros((4, 4, 3), np.uint8)
    blue[..., 2] = 255
    write_image(tmp_path / "a.png", red)
    write_image(tmp_path / "b.png", blue)
    header = ("ply\nformat ascii 1.0\ncomment TextureFile a.png\ncomment TextureFile b.png\nelement vertex 4\n"
              "property float x\nproperty float y\nproperty float z\nelement face 2\n"
              "property list uchar int vertex_indices\nproperty list uchar float texcoord\nproperty int texnumber\n"
              "end_header\n")
    body = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2 6 0 0 1 0 1 1 0\n3 0 2 3 6 0 0 1 1 0 1 1\n"
    (tmp_path / "m.ply").write_text(header + body)
    mesh = read_mesh(tmp_path / "m.ply")
    centre = np.full((2, 3), 1.0 / 3.0)
    assert np.allclose(surface_colors(mesh, [0, 1], centre), [[1, 0, 0], [0, 0, 1]])


def test_a_material_without_an_image_packs_as_its_diffuse_colour(tmp_path):
    write_image(tmp_path / "t.png", _image(4, 4, seed=7))
    (tmp_path / "m.mtl").write_text("newmtl a\nmap_Kd t.png\nnewmtl plain\nKd 0 1 0\n")
    (tmp_path / "m.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                    "usemtl a\nf 1/1 2/2 3/3\nusemtl plain\nf 2/1 4/2 3/3\n")
    mesh = read_mesh(tmp_path / "m.obj")
    assert np.allclose(surface_colors(mesh, [1], [[1 / 3, 1 / 3, 1 / 3]]), [[0, 1, 0]])
