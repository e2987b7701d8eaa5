"""remove_wrinkles (Bickel et al. 2007, 5.4): generated wrinkles removed, a known fine detail kept, the rest untouched.

The truth comes from the generator (``facecap.synth.wrinkles``: its own valley-and-bulge height
field, not the solver's), on the ICT face subdivided twice as ``wrinkle_scan.py`` builds it
(148k vertices, 0.9 mm edges on the forehead; the removal cuts out and solves only the region,
about 10-15k vertices here).
"""

from functools import lru_cache

import igl
import numpy as np
import pytest

from facecap.errors import FacecapWarning, InputError
from facecap.structures import Mesh
from facecap.io.ict_sample import load_ict_sample
from facecap.synth.wrinkle_scan import subdivide_scan
from facecap.synth.wrinkles import WRINKLE_EXPRESSIONS, add_wrinkles, place_wrinkles
from facecap.wrinkles import remove_wrinkles, remove_wrinkles_arrays

DETAIL_AMPLITUDE_MM = 0.03
DETAIL_WAVELENGTH_MM = 2.5  # bumps 1.25 mm across: under three vertex spacings of this mesh


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


@lru_cache(maxsize=1)
def _case():
    """Smooth face, its normals, the forehead and frown wrinkles at full strength, and a bump pattern."""
    sample = load_ict_sample()
    fine = subdivide_scan(sample.mesh, levels=2)
    V, F = fine.mesh.vertices, fine.mesh.faces
    curves = place_wrinkles(fine.mesh, sample, kinds=("forehead", "glabella"), seed=0)
    names = sample.expression_names
    weights = np.zeros((1, len(names)))
    for expression in ("brow_raise", "frown"):  # the strong expressions that make these wrinkles
        for shape, w in WRINKLE_EXPRESSIONS[expression].items():
            weights[0, names.index(shape)] = max(weights[0, names.index(shape)], w)
    wrinkled = add_wrinkles(V[None].astype(np.float32), F, curves, weights, rest=V)
    assert wrinkled.activation.min() > 0.99
    heights = wrinkled.heights[0].astype(np.float64)
    normals = igl.per_vertex_normals(V, F, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_AREA)
    detail = (DETAIL_AMPLITUDE_MM * np.sin(2 * np.pi * V[:, 0] / DETAIL_WAVELENGTH_MM)
              * np.sin(2 * np.pi * V[:, 1] / DETAIL_WAVELENGTH_MM))
    return V, F, normals, heights, wrinkled.mask, detail


@lru_cache(maxsize=None)
def _removed(with_wrinkles: bool, with_detail: bool):
    V, F, normals, heights, mask, detail = _case()
    height = (heights if with_wrinkles else 0.0) + (detail if with_detail else 0.0) + np.zeros(V.shape[0])
    scan = V + height[:, None] * normals
    return scan, remove_wrinkles_arrays(scan, F, mask)


def test_generated_wrinkles_are_removed_and_the_fine_detail_kept():
    V, F, normals, heights, mask, detail = _case()
    scan, out = _removed(True, True)
    changed = out.changed
    assert changed.sum() > 0.95 * mask.sum()  # only the region's vertices on the mesh's boundaries stay
    truth = V + detail[:, None] * normals  # the same scan without its wrinkles
    residual = np.einsum("nd,nd->n", out.vertices - truth, normals)[mask]
    wrinkle = heights[mask]
    # measured: residual 0.043 mm RMS (0.23 of the wrinkles' 0.19 mm), 0.19 mm at most (valleys 0.79 mm deep);
    # the paper's plain steady state leaves 0.11 mm RMS (below)
    assert _rms(residual) < 0.25 * _rms(wrinkle)
    assert np.abs(residual).max() < 0.3 * np.abs(wrinkle).max()
    # the detail in the result: with and without it in the scan, the rest alike
    _, plain = _removed(True, False)
    kept = np.einsum("nd,nd->n", out.vertices - plain.vertices, normals)[changed]
    assert np.corrcoef(kept, detail[changed])[0, 1] > 0.7  # measured 0.76
    assert 0.6 < _rms(kept) / _rms(detail[changed]) < 1.05  # measured 0.76
    # without the detail step (detail_scale_mm=0) the bi-Laplacian patch smooths it away
    bare = remove_wrinkles_arrays(scan, F, mask, detail_scale_mm=0.0)
    lost = np.einsum("nd,nd->n", bare.vertices - plain.vertices, normals)[changed]
    assert abs(np.corrcoef(lost, detail[changed])[0, 1]) < 0.2


def test_the_bilaplacian_detail_smoothing_keeps_more_of_the_detail():
    V, F, normals, heights, mask, detail = _case()
    scan, _ = _removed(True, True)
    wrinkled = V + heights[:, None] * normals
    a = remove_wrinkles_arrays(wrinkled, F, mask, detail_smoothing="bilaplacian")
    b = remove_wrinkles_arrays(scan, F, mask, detail_smoothing="bilaplacian")
    kept = np.einsum("nd,nd->n", b.vertices - a.vertices, normals)[a.changed]
    assert np.corrcoef(kept, detail[a.changed])[0, 1] > 0.95  # measured 0.99 (the Laplacian's: 0.76)
    assert 0.8 < _rms(kept) / _rms(detail[a.changed]) < 1.05  # measured 0.91
    residual = np.einsum("nd,nd->n", b.vertices - (V + detail[:, None] * normals), normals)[mask]
    assert _rms(residual) < 0.25 * _rms(heights[mask])  # measured 0.042 mm, as the Laplacian's
    np.testing.assert_array_equal(b.vertices[~mask], scan[~mask])


def test_vertices_outside_the_region_are_unchanged_exactly():
    V, F, normals, heights, mask, detail = _case()
    scan, out = _removed(True, True)
    np.testing.assert_array_equal(out.vertices[~mask], scan[~mask])
    assert not out.changed[~mask].any()
    # and the mesh record keeps everything but the vertices
    mesh = Mesh(scan, F, source_unit="cm")
    result = remove_wrinkles(mesh, mask)
    assert result.source_unit == "cm" and result.faces is mesh.faces
    np.testing.assert_array_equal(result.vertices, out.vertices)


def test_a_smooth_surface_without_wrinkles_passes_through_nearly_unchanged():
    V, F, normals, heights, mask, detail = _case()
    _, out = _removed(False, False)
    moved = np.einsum("nd,nd->n", out.vertices - V, normals)[mask]
    # measured 0.021 mm RMS, 0.09 mm at most (the subdivided ICT face is faceted at 3.75 mm)
    assert _rms(moved) < 0.03
    assert np.abs(moved).max() < 0.15
    # the paper's plain steady state (no large-scale reference) loses more of the face's shape
    plain = remove_wrinkles_arrays(V, F, mask, large_scale_mm=None)
    assert _rms(np.einsum("nd,nd->n", plain.vertices - V, normals)[mask]) > 2 * _rms(moved)


def test_the_plain_steady_state_is_libigls_biharmonic_solve():
    sample = load_ict_sample()
    fine = subdivide_scan(sample.mesh, levels=1)
    V, F = fine.mesh.vertices, fine.mesh.faces
    forehead = sample.region_labels == sample.region_names.index("forehead")
    middle = V[: sample.n_vertices][forehead].mean(axis=0)
    centre = V[np.argmin(np.linalg.norm(V - middle, axis=1))]  # the middle of the forehead, away from its edges
    region = np.linalg.norm(V - centre, axis=1) < 15.0
    out = remove_wrinkles_arrays(V, F, region, detail_scale_mm=0.0, large_scale_mm=None, backend="scipy")
    assert out.changed.sum() == region.sum() > 100
    fixed = np.flatnonzero(~region)
    reference = igl.harmonic(V, F, fixed, V[fixed], 2)  # min x^T L M^-1 L x, the rest fixed
    np.testing.assert_allclose(out.vertices, reference, atol=1e-8)


def test_a_closed_piece_inside_the_region_is_left_alone_with_a_warning():
    # an octahedron refined twice: closed, nothing outside the region to hold it
    V = np.array([[1.0, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]) * 10.0
    F = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    V, F = igl.upsample(V, F, 2)
    with pytest.warns(FacecapWarning, match="closed pieces"):
        out = remove_wrinkles_arrays(V, F, backend="scipy")
    np.testing.assert_array_equal(out.vertices, V)
    assert not out.changed.any()


def test_bad_region_mask_and_options_raise_input_errors_naming_them():
    V, F, *_ = _case()
    with pytest.raises(InputError, match=r"region_mask: .*length 148402.*\(100,\)"):
        remove_wrinkles_arrays(V, F, np.zeros(100, dtype=bool))
    with pytest.raises(InputError, match="region_mask: expected a boolean"):
        remove_wrinkles_arrays(V, F, np.zeros(V.shape[0], dtype=np.int64))
    with pytest.raises(InputError, match="detail_scale_mm"):
        remove_wrinkles_arrays(V, F, detail_scale_mm=-1.0)
    with pytest.raises(InputError, match="large_scale_mm"):
        remove_wrinkles_arrays(V, F, large_scale_mm=0.0)
    with pytest.raises(InputError, match="smoothing_steps"):
        remove_wrinkles_arrays(V, F, smoothing_steps=0)
    with pytest.raises(InputError, match="detail_smoothing"):
        remove_wrinkles_arrays(V, F, detail_smoothing="gaussian")
    with pytest.raises(InputError, match="mesh: expected a facecap Mesh"):
        remove_wrinkles(V)


def test_a_uv_seam_is_welded_for_the_solve():
    # a valley across a 0.5 mm grid, and the same grid cut along a column (its vertices duplicated there)
    k = 41
    x, y = np.meshgrid(np.arange(k) * 0.5, np.arange(k) * 0.5)
    q = (y.ravel() - 10.0) / 2.0
    V = np.stack([x.ravel(), y.ravel(), -0.4 * (1 - q**2) * np.exp(-q**2)], 1)
    a = (np.arange(k - 1)[:, None] * k + np.arange(k - 1)[None]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + k + 1], 1), np.stack([a, a + k + 1, a + k], 1)])
    region = (np.abs(q) < 3) & (np.abs(V[:, 0] - 10.0) < 7)
    seam = np.flatnonzero(np.isclose(V[:, 0], 10.0))
    copy = np.arange(V.shape[0])
    copy[seam] = V.shape[0] + np.arange(seam.size)
    right = np.all(V[F, 0] >= 10.0 - 1e-9, axis=1)
    F_cut = np.where(right[:, None], copy[F], F)
    V_cut = np.concatenate([V, V[seam]])
    region_cut = np.concatenate([region, region[seam]])
    whole = remove_wrinkles_arrays(V, F, region, backend="scipy")
    cut = remove_wrinkles_arrays(V_cut, F_cut, region_cut, backend="scipy")
    assert whole.changed[seam].any()  # the seam runs through the region
    np.testing.assert_allclose(cut.vertices[: V.shape[0]], whole.vertices, atol=1e-9)
    np.testing.assert_allclose(cut.vertices[V.shape[0]:], whole.vertices[seam], atol=1e-9)
