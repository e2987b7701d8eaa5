"""Tests for facecap.registration.align_albedo: a known slide along the skin undone by the skin's colour."""

from __future__ import annotations

import igl
import numpy as np
import pytest

from facecap.errors import InputError
from facecap.registration.align_albedo import align_albedo
from facecap.structures import Mesh
from facecap.synth import scan_expression
from facecap.io.ict_sample import load_ict_sample


def _texture(points: np.ndarray) -> np.ndarray:
    """A solid skin-like texture (3-10 mm random-phase waves), independent of the package's own."""
    rng = np.random.default_rng(7)
    k = rng.normal(size=(300, 3))
    k *= (2 * np.pi / rng.uniform(3.0, 10.0, 300) / np.linalg.norm(k, axis=1))[:, None]
    phase = rng.uniform(0, 2 * np.pi, 300)
    tone = 0.45 + 0.05 * np.cos(points @ k.T + phase).sum(axis=1) / np.sqrt(150)
    return np.clip(tone[:, None] * np.array([1.0, 0.75, 0.62]), 0, 1)


def _coloured_scan(V, F, seed, exposure):
    scanned = scan_expression(V, F, seed=seed, target_vertices=30000, scanner_from_face=np.eye(4))
    material = np.einsum("sk,skc->sc", scanned.barycentric, V[F[scanned.source_faces]])
    noise = np.random.default_rng(seed).normal(scale=0.01, size=material.shape)
    colours = np.clip(exposure * _texture(material) + noise, 0, 1).astype(np.float32)
    return Mesh(scanned.mesh.vertices, scanned.mesh.faces, vertex_colors=colours)


@pytest.fixture(scope="module")
def slid_face():
    s = load_ict_sample()
    V, F = s.mesh.vertices, s.mesh.faces
    scan = _coloured_scan(V, F, seed=1, exposure=1.1)  # what the scanner saw, its own exposure
    texture = _coloured_scan(V, F, seed=2, exposure=0.9)  # the template's own coloured scan
    # the registration slid the skin: up to 1.5 mm upwards, smoothly, along the surface
    normals = igl.per_vertex_normals(V, F)
    up = np.array([0.0, 1.0, 0.0])
    tangential = up - np.einsum("nc,c->n", normals, up)[:, None] * normals
    amount = 1.5 * np.exp(-((V[:, 0] / 45.0) ** 2 + ((V[:, 1] - 30.0) / 40.0) ** 2))
    slid = V + amount[:, None] * tangential
    _, _, on_surface = igl.point_mesh_squared_distance(slid, V, F)
    return s, V, F, scan, texture, on_surface, amount


def test_a_known_slide_along_the_skin_is_undone(slid_face):
    s, V, F, scan, texture, slid, amount = slid_face
    moved = amount > 0.5
    before = np.linalg.norm(slid - V, axis=1)
    result = align_albedo(slid, F, V, texture, scan)
    after = np.linalg.norm(result.vertices - V, axis=1)
    seen = result.confidence > 0.1
    assert before[moved & seen].mean() > 0.7  # the slide is real (0.85 mm there, up to 1.5)
    assert after[moved & seen].mean() < 0.35 * before[moved & seen].mean()  # measured 0.85 -> 0.19 mm
    # on the scan still (the update is put back onto the surface), and it did not tear the mesh
    sq, _, _ = igl.point_mesh_squared_distance(result.vertices[seen], scan.vertices, scan.faces)
    assert np.sqrt(sq).mean() < 0.1


def test_a_correct_registration_stays(slid_face):
    s, V, F, scan, texture, _, _ = slid_face
    result = align_albedo(V, F, V, texture, scan)
    assert np.linalg.norm(result.vertices - V, axis=1).mean() < 0.1


def test_a_factor_kept_between_scans_gives_the_same_alignment_and_one_analysis(slid_face):
    # a run of scans shares the update's factor: the same answer as a factor of its own, and PARDISO's
    # analysis (the solver object holding it) survives from one scan to the next
    from facecap.mesh.factor_spd import SpdFactor
    from facecap.mesh.weld_duplicate_vertices import weld_duplicate_vertices
    from facecap.registration.align_albedo import SEAM_WELD_MM

    s, V, F, scan, texture, slid, _ = slid_face
    alone = align_albedo(slid, F, V, texture, scan)
    factor = SpdFactor.unfactored(weld_duplicate_vertices(slid, F, tolerance=SEAM_WELD_MM).V.shape[0])
    try:
        first = align_albedo(slid, F, V, texture, scan, factor=factor)
        solver = factor._impl[0]
        second = align_albedo(V, F, V, texture, scan, factor=factor)
        assert factor._impl[0] is solver or factor.backend != "pardiso"  # PARDISO's solver, its analysis kept
    finally:
        factor.free()
    np.testing.assert_allclose(first.vertices, alone.vertices, atol=1e-6)
    np.testing.assert_allclose(second.vertices, align_albedo(V, F, V, texture, scan).vertices, atol=1e-6)
    with pytest.raises(InputError, match="factor"):
        align_albedo(slid, F, V, texture, scan, factor="mine")


def test_uncoloured_inputs_are_refused(slid_face):
    s, V, F, scan, texture, _, _ = slid_face
    bare = Mesh(scan.vertices, scan.faces)
    with pytest.raises(InputError, match="vertex_colors"):
        align_albedo(V, F, V, texture, bare)
    with pytest.raises(InputError, match="template_rest"):
        align_albedo(V, F, V[:10], texture, scan)


def test_register_scans_slides_the_bases_by_colour_when_asked():
    # Two strong brow expressions scanned with a dense skin texture, the neutral's own coloured
    # scan as the template's texture: with align_colors the bases at their own frames are closer
    # to the truth than from geometry and markers alone.
    from facecap.registration import register_scans
    from facecap.synth import generate_performance

    s = load_ict_sample()
    names = s.expression_names
    weights = np.zeros((3, len(names)))
    for t, shapes in ((1, ("browInnerUp_L", "browInnerUp_R", "browOuterUp_L", "browOuterUp_R")),
                      (2, ("browDown_L", "browDown_R", "eyeSquint_L", "eyeSquint_R"))):
        weights[t, [names.index(n) for n in shapes]] = 1.0
    case = generate_performance(curves=weights, seed=3, noise_mm=0.0, gap_fraction=0.0, head_rotation_deg=0.0,
                                head_translation_mm=0.0)
    V0, F = case.scan.vertices, case.scan.faces
    # the scans' colours follow the skin: each scan vertex coloured at its material point
    recoloured = []
    for t in (1, 2):
        scanned = scan_expression(case.truth_vertices[t], F, seed=10 + t, target_vertices=30000,
                                  scanner_from_face=np.eye(4))
        material = np.einsum("sk,skc->sc", scanned.barycentric, V0[F[scanned.source_faces]])
        recoloured.append(Mesh(scanned.mesh.vertices, scanned.mesh.faces,
                               vertex_colors=np.clip(_texture(material), 0, 1).astype(np.float32)))
    texture = _coloured_scan(V0, F, seed=20, exposure=1.0)
    markers = case.markers.positions[[1, 2]]
    common = dict(template=case.scan, template_markers=case.markers.positions[0], progress=False)
    plain = register_scans(recoloured, markers, **common)
    slid = register_scans(recoloured, markers, template_texture=texture, align_colors=True, **common)
    truth = case.truth_vertices[[1, 2]].astype(np.float64)

    def error(result):
        A = result.output_from_mocap
        return np.linalg.norm(result.bases @ A[:3, :3].T + A[:3, 3] - truth, axis=2).mean(axis=1)

    # measured 0.358 -> 0.259 and 0.255 -> 0.242 mm
    assert error(slid).mean() < 0.85 * error(plain).mean() and np.all(error(slid) <= error(plain)), (
        error(plain), error(slid))
    assert all("colour_alignment_moved_mm" in scan for scan in slid.report["scans"])
    with pytest.raises(InputError, match="vertex colours"):
        register_scans([Mesh(m.vertices, m.faces) for m in recoloured], markers, template_texture=texture,
                       align_colors=True, **common)


def _fine_skin(face):
    """Skin-like detail at 0.3-3 mm in the face's own atlas (octaves of blurred noise), not the package's skin."""
    import cv2

    from facecap.io.write_gltf import triangle_corners
    from facecap.synth import SkinTexture

    rng = np.random.default_rng(11)
    size = 1024  # 0.29 mm a texel on this face
    detail = sum(a * s * cv2.GaussianBlur(rng.normal(size=(size, size)), (0, 0), s)
                 for a, s in ((1.0, 1.0), (0.6, 3.0), (0.4, 8.0)))
    detail /= detail.std()
    image = np.clip(0.4 * (1.0 + 0.15 * detail), 0.0, 1.0)[:, :, None] * np.array([1.0, 0.75, 0.62])
    return SkinTexture(image.astype(np.float32), face.uvs, np.asarray(face.uv_indices)[triangle_corners(face)])


def test_a_known_slide_is_undone_by_the_scans_texture(slid_face):
    # scanners deliver a colour texture at 0.25 mm: the scan's own atlas against the neutral's
    from facecap.synth import textured_neutral

    s, V, F, _, _, slid, amount = slid_face
    skin = _fine_skin(s.mesh)
    scan = scan_expression(V, F, seed=1, target_vertices=20000, scanner_from_face=np.eye(4), skin_texture=skin).mesh
    neutral = textured_neutral(s.mesh, skin, seed=2)
    moved = amount > 0.5
    before = np.linalg.norm(slid - V, axis=1)
    result = align_albedo(slid, F, V, neutral, scan)
    after = np.linalg.norm(result.vertices - V, axis=1)
    seen = result.confidence > 0.1
    assert before[moved & seen].mean() > 0.7
    assert after[moved & seen].mean() < 0.3 * before[moved & seen].mean(), (  # measured 0.84 -> 0.13 mm
        before[moved & seen].mean(), after[moved & seen].mean())
    # the images agree better after the first round's slide (what register-scans reports per basis)
    first, second = result.mismatch_by_round
    assert second < 0.9 * first, result.mismatch_by_round
