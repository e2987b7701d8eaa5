"""The camera's blur on the skin: a Gaussian of the image distance, weighted by area, rows summing to 1."""

import numpy as np

from facecap.sfs.camera_blur import camera_blur


def test_rows_are_the_gaussian_of_the_image_distance_times_the_area():
    rng = np.random.default_rng(0)
    pixels = rng.uniform(0, 20, size=(400, 2))
    area = rng.uniform(0.05, 0.1, size=400)
    B = camera_blur(pixels, area, 1.0, reach=3.0)
    np.testing.assert_allclose(np.asarray(B.sum(axis=1)).ravel(), 1.0)
    i = 17
    d2 = np.sum((pixels - pixels[i]) ** 2, axis=1)
    w = np.where(d2 <= 9.0, np.exp(-0.5 * d2) * area, 0.0)
    np.testing.assert_allclose(B[i].toarray().ravel(), w / w.sum(), atol=1e-12)


def test_a_line_one_sample_wide_loses_contrast_as_the_blur_widens():
    x, y = np.meshgrid(np.arange(30.0), np.arange(30.0))
    pixels = np.c_[x.ravel(), y.ravel()] * 1.4  # 1.4 px between samples
    line = (x.ravel() == 15).astype(float)
    contrasts = [(camera_blur(pixels, np.ones(900), s) @ line)[line > 0].mean() for s in (0.0, 0.6, 0.8, 1.2)]
    assert contrasts[0] == 1.0 and contrasts[0] > contrasts[1] > contrasts[2] > contrasts[3]
    # at s = 0.8 the reach (2 px) holds the 4 neighbours at 1.4 px (2 on the line) and the 4 diagonal ones
    # at 1.98 px (none on it)
    e1, e2 = np.exp(-1.96 / 1.28), np.exp(-3.92 / 1.28)
    np.testing.assert_allclose(contrasts[2], (1 + 2 * e1) / (1 + 4 * e1 + 4 * e2), rtol=1e-9)


def test_the_blur_in_the_region_numbering_keeps_unseen_samples_to_themselves():
    import scipy.sparse as sp

    from facecap.sfs.detail_frame_stage import _in_region

    rng = np.random.default_rng(2)
    size = 60
    rows = np.sort(rng.choice(size, 41, replace=False))
    inner = camera_blur(rng.uniform(0, 4, size=(41, 2)), rng.uniform(0.5, 1.5, 41), 0.7)
    embed = sp.csr_matrix((np.ones(41), (rows, np.arange(41))), shape=(size, 41))
    unseen = np.ones(size)
    unseen[rows] = 0.0
    expected = (embed @ inner @ embed.T + sp.diags(unseen)).toarray()
    assert np.array_equal(_in_region(inner, rows, size).toarray(), expected)
