import json
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facecap.pipelines.animate_scan import animate_scan
from facecap.deform.marker_offsets import MarkerOffsets, marker_ring
from facecap.deform.thin_shell import ThinShellSolver
from facecap.errors import FacecapWarning, InputError
from facecap.io import read_correspondence
from facecap.synth import generate_performance

H = 1.5


def _flat_grid(n=25, spacing=4.0):
    g = (np.arange(n) - (n - 1) / 2) * spacing
    x, y = np.meshgrid(g, g)
    V = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], axis=1)
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + n], 1), np.stack([a + 1, a + n + 1, a + n], 1)])
    return V, F


def _interior_markers(n=25, step=4):
    ij = np.arange(step, n - step, step)
    return (ij[:, None] * n + ij[None]).ravel()


def _reference_normals(X, F, vertices):
    """Slow, obvious area-weighted vertex normals: a loop over each vertex's triangles."""
    out = []
    for v in vertices:
        N = np.zeros(3)
        for f in F[(F == v).any(axis=1)]:
            N += np.cross(X[f[1]] - X[f[0]], X[f[2]] - X[f[0]])
        out.append(N / np.linalg.norm(N))
    return np.array(out)


def test_rotated_grid_gives_the_skin_displacement_back():
    # a flat sheet turned rigidly by 0.2 rad: markers 1.5 mm up move h (R n - n) more than the skin.
    # Markers on the whole rim and a harmonic shell (kb = 0) reproduce the turn exactly, so the
    # deformed normals are R n and the corrected displacement is the skin's to float32 rounding.
    n = 17
    V, F = _flat_grid(n)
    i, j = np.divmod(np.arange(n * n), n)
    mv = np.flatnonzero((i == 0) | (j == 0) | (i == n - 1) | (j == n - 1) | ((i % 4 == 0) & (j % 4 == 0)))
    shell = ThinShellSolver(V, F, mv, kb=0.0)
    offsets = MarkerOffsets(V, F, shell, marker_offset_mm=H)
    np.testing.assert_allclose(offsets.rest_normals, np.tile([0.0, 0.0, 1.0], (mv.size, 1)), atol=1e-12)
    angle = 0.2
    R = Rotation.from_rotvec([0.0, angle, 0.0]).as_matrix()
    skin = (V[mv] @ R.T - V[mv])[None]  # (1, K, 3)
    marker = skin + H * (offsets.rest_normals @ R.T - offsets.rest_normals)[None]
    uncorrected = np.linalg.norm(marker - skin, axis=2)
    np.testing.assert_allclose(uncorrected, 2 * H * np.sin(angle / 2), rtol=1e-9)  # ~ h * angle = 0.3 mm
    np.testing.assert_allclose(offsets.deformed_normals(skin)[0], offsets.rest_normals @ R.T, atol=1e-6)
    corrected = np.linalg.norm(offsets.skin_displacements(marker) - skin, axis=2)
    assert corrected.max() < 1e-5


def test_fixed_point_and_normals_against_a_slow_reference():
    V, F = _flat_grid()
    V[:, 2] = 0.004 * V[:, 0] ** 2 - 0.002 * V[:, 1] ** 2  # curved, so rest normals differ
    mv = _interior_markers()
    shell = ThinShellSolver(V, F, mv)
    offsets = MarkerOffsets(V, F, shell, marker_offset_mm=H)
    rng = np.random.default_rng(0)
    skin = rng.normal(scale=1.5, size=(3, mv.size, 3))
    full = V[None] + shell.displacements(skin).astype(np.float64)
    reference = np.stack([_reference_normals(X, F, mv) for X in full])
    np.testing.assert_allclose(offsets.deformed_normals(skin), reference, atol=1e-5)
    np.testing.assert_allclose(offsets.rest_normals, _reference_normals(V, F, mv), atol=1e-6)  # float32 inside
    # markers exactly h above the deformed shell: two fixed-point steps recover the skin
    marker = skin + H * (reference - offsets.rest_normals[None])
    assert np.abs(offsets.skin_displacements(marker) - skin).max() < 0.02 * np.abs(marker - skin).max()
    assert np.array_equal(MarkerOffsets(V, F, shell, marker_offset_mm=0.0).skin_displacements(marker), marker)
    # the mesh side built before the shell (marker_ring, from V, F and the marker vertices alone) gives the same
    ring = marker_ring(V, F, mv)
    np.testing.assert_allclose(ring.rest_normals, _reference_normals(V, F, mv), atol=1e-6)
    early = MarkerOffsets(V, F, shell, marker_offset_mm=H, ring=ring)
    assert np.array_equal(early.rest_normals, offsets.rest_normals)
    assert np.array_equal(early.skin_displacements(marker), offsets.skin_displacements(marker))
    with pytest.raises(InputError, match="other marker vertices"):
        MarkerOffsets(V, F, shell, ring=marker_ring(V, F, mv[:-1]))


def test_bad_input_is_named():
    V, F = _flat_grid()
    mv = _interior_markers()
    shell = ThinShellSolver(V, F, mv)
    with pytest.raises(InputError, match="marker_offset_mm"):
        MarkerOffsets(V, F, shell, marker_offset_mm=-1.0)
    with pytest.raises(InputError, match="iterations"):
        MarkerOffsets(V, F, shell, iterations=-1)
    offsets = MarkerOffsets(V, F, shell)
    with pytest.raises(InputError, match="marker_displacements"):
        offsets.skin_displacements(np.zeros((2, mv.size + 1, 3)))
    with pytest.raises(InputError, match="NaN"):
        offsets.skin_displacements(np.full((1, mv.size, 3), np.nan))


@pytest.fixture(scope="module")
def generated_results(tmp_path_factory):
    # 1.5 mm markers, no noise, gaps or head motion: what is left is the offset
    case = generate_performance(n_frames=90, n_markers=40, seed=1, noise_mm=0.0, gap_fraction=0.0,
                                head_rotation_deg=0.0, head_translation_mm=0.0, headband_markers=0)
    root = tmp_path_factory.mktemp("offsets")
    (root / "map.json").write_text(json.dumps(case.correspondence))
    corr = read_correspondence(root / "map.json", case.scan)
    out = {}
    for name, options in {"off": {"marker_offset_mm": 0.0}, "default": {}}.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FacecapWarning)
            animate_scan(case.scan, case.markers, corr, root / name, progress=False, smooth=False, **options)
        out[name] = root / name
    return case, out


def test_corrected_animation_is_closer_at_the_markers(generated_results):
    case, folders = generated_results
    mv = case.marker_vertices
    truth = case.truth_vertices[:, mv]
    err = {k: np.linalg.norm(np.load(p / "vertices.npy")[:, mv] - truth, axis=2).mean() for k, p in folders.items()}
    assert err["default"] < 0.5 * err["off"]


def test_offset_is_on_by_default_and_recorded(generated_results):
    _, folders = generated_results
    info = {k: json.loads((p / "performance.json").read_text())["parameters"] for k, p in folders.items()}
    assert info["default"]["marker_offset_mm"] == 1.5 and info["off"]["marker_offset_mm"] == 0.0
    assert info["default"]["rest_average_s"] == 0.1
    report = json.loads((folders["default"] / "report.json").read_text())
    assert report["marker_residual_mm"]["max"] < 0.01  # the fixed point has converged
    assert report["marker_offset_correction_mm"]["max"] > 0.05


def test_cli_marker_offset_option(capture_case, tmp_path, capsys):
    from facecap.cli import main

    def animate(out, *extra):
        return main(["--quiet", "animate", "--scan", str(capture_case.scan_path), "--markers",
                     str(capture_case.markers_path), "--map", str(capture_case.map_path), "--out", str(out), *extra])

    assert animate(tmp_path / "a", "--marker-offset", "0", "--rest-average", "0") == 0
    parameters = json.loads((tmp_path / "a" / "performance.json").read_text())["parameters"]
    assert parameters["marker_offset_mm"] == 0.0 and parameters["rest_average_s"] == 0.0
    assert animate(tmp_path / "b", "--marker-offset", "-1") == 2
    assert "marker_offset_mm" in capsys.readouterr().err
