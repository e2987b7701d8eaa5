"""Tests for facecap.synth.real_motion_curves: ICT weights fitted to the bundled real take."""

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.io import read_markers
from facecap.markers import condition_take, rigid_fit
from facecap.mesh.vertex_normals import vertex_normals
from facecap.io.ict_sample import bundled_path, load_ict_sample
from facecap.synth.marker_layout import animface_marker_map
from facecap.synth.real_motion_curves import REAL_CURVE_NAMES, load_real_curve_fit, real_motion_curves


def test_stored_fit_explains_the_real_take_far_better_than_no_motion():
    # recompute the marker residual of the stored weights on the real take, independently of the tool
    fit = load_real_curve_fit()
    s = load_ict_sample()
    assert fit.names == s.expression_names == REAL_CURVE_NAMES and fit.weights.shape == (902, 53)
    assert fit.weights.min() >= 0 and fit.weights.max() <= 1 and np.all(fit.weights[0] == 0)
    take = read_markers(bundled_path("eyebrows.c3d"))
    m = animface_marker_map()
    index = take.label_index()
    P = condition_take(take, stabilize=True).positions[:, [index[k] for k in m]]
    mv = np.array(list(m.values()))
    V, F = s.mesh.vertices, s.mesh.faces
    align = rigid_fit(P[0], V[mv] + 1.5 * vertex_normals(V, F, mv))
    D = align.apply(P) - align.apply(P[:1])
    model = np.tensordot(fit.weights, s.expression_deltas[:, mv], axes=1)
    rms = float(np.sqrt(np.mean(np.sum((model - D) ** 2, axis=2))))
    zero = float(np.sqrt(np.mean(np.sum(D**2, axis=2))))
    assert rms < 2.0 and rms < 0.65 * zero  # measured: 1.85 mm against 3.09 mm
    assert abs(rms - fit.residual_rms_mm) < 0.1 and abs(zero - fit.zero_weights_rms_mm) < 0.1
    # the take is a brow take: the brows are what moves most
    peak = dict(zip(fit.names, fit.weights.max(axis=0)))
    assert max(peak["browInnerUp_L"], peak["browOuterUp_L"], peak["browDown_L"]) > 0.8


def test_default_plays_the_take_and_other_seeds_shuffle_it():
    fit = load_real_curve_fit()
    W = real_motion_curves()
    assert W.shape == (902, 53) and np.all(W[0] == 0)
    np.testing.assert_allclose(W[15:], fit.weights[15:], atol=1e-12)  # after the 0.25 s ease-in
    long = real_motion_curves(3000, seed=7)
    assert long.shape == (3000, 53) and np.all(long[0] == 0) and long.min() >= 0 and long.max() <= 1
    assert np.abs(np.diff(long, axis=0)).max() < 0.25  # crossfaded joins, no jumps
    assert not np.allclose(long[:902], W)
    np.testing.assert_array_equal(long, real_motion_curves(3000, seed=7))


def test_resampling_follows_time_not_frames():
    W60 = real_motion_curves(600, rate=60.0)
    W120 = real_motion_curves(1200, rate=120.0)
    np.testing.assert_allclose(W120[::2], W60, atol=1e-12)


def test_asymmetry_and_timing_offset_separate_the_sides():
    names = list(REAL_CURVE_NAMES)
    W = real_motion_curves(900, seed=2, asymmetry=0.3, max_timing_offset_s=0.1)
    L, R = W[:, names.index("browInnerUp_L")], W[:, names.index("browInnerUp_R")]
    base = real_motion_curves(900, seed=2)
    assert np.abs(L - R).max() > 0.05 and np.abs(base[:, names.index("browInnerUp_L")] - L).max() > 0.02
    with pytest.raises(InputError, match="asymmetry"):
        real_motion_curves(10, asymmetry=1.0)
    with pytest.raises(InputError, match="n_frames"):
        real_motion_curves(0)
