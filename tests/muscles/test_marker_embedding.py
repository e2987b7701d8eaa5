"""marker_embedding: the embedded skin points, the rest offsets, markers off the model."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import CorrespondenceError, InputError
from facecap.muscles import marker_embedding


def test_embedding_reproduces_the_markers(anatomy, layout) -> None:
    e = marker_embedding(anatomy, layout.marker_vertices, layout.rest_markers)
    assert e.matrix.shape == (layout.marker_vertices.size, anatomy.n_nodes)
    skin = e.matrix @ anatomy.nodes
    assert np.abs(skin - anatomy.scan_vertices[layout.marker_vertices]).max() < 1e-9
    assert np.allclose(skin + e.offsets, layout.rest_markers, atol=1e-12)
    assert np.allclose(np.linalg.norm(e.offsets, axis=1), 1.5, atol=1e-6)  # markers 1.5 mm above the skin
    assert np.allclose(np.asarray(e.matrix.sum(axis=1)).ravel(), 1.0)


def test_markers_off_the_model_are_refused(anatomy, layout) -> None:
    outside = int(np.flatnonzero(~anatomy.skin_meshed)[0])  # ears, scalp, neck
    vertices = layout.marker_vertices.copy()
    vertices[3] = outside
    with pytest.raises(CorrespondenceError, match=r"markers \[3\] land off the model"):
        marker_embedding(anatomy, vertices, layout.rest_markers)
    with pytest.raises(CorrespondenceError, match="indices span"):
        marker_embedding(anatomy, np.array([0, anatomy.scan_vertices.shape[0]]), layout.rest_markers[:2])
    far = layout.rest_markers.copy()
    far[5] += [0, 0, 25.0]
    with pytest.raises(InputError, match=r"markers \[5\] lie more than 10.0 mm"):
        marker_embedding(anatomy, layout.marker_vertices, far)
    with pytest.raises(InputError, match="rows"):
        marker_embedding(anatomy, layout.marker_vertices, layout.rest_markers[:-1])
    with pytest.raises(InputError, match="NaN"):
        marker_embedding(anatomy, layout.marker_vertices, np.full_like(layout.rest_markers, np.nan))
