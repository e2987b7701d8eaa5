"""The small analytic capture case shared by the tests, independent of the ICT generator.

Importable as ``analytic_case`` (``tests/`` is on the path): the fixtures in
``tests/conftest.py`` build on it, and tests that need it outside a fixture
import it.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from facecap.io import write_markers, write_mesh
from facecap.structures import MarkerSequence, Mesh

def curved_grid(n: int = 20, size: float = 120.0) -> tuple[np.ndarray, np.ndarray]:
    """A face-sized curved sheet (mm) of 2 (n-1)^2 triangles."""
    u, v = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    x, y = (u.ravel() - 0.5) * size, (v.ravel() - 0.5) * size
    V = np.stack([x, y, -0.006 * x**2 - 0.003 * y**2], axis=1)
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None]).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + n], 1), np.stack([a + 1, a + n + 1, a + n], 1)])
    return V, F


def smooth_field(P: np.ndarray, t: np.ndarray) -> np.ndarray:
    """A smooth, time-varying displacement field (mm), zero at t = 0: the 'expression'."""
    s = np.sin(np.pi * t)[:, None, None]
    return s * np.stack(
        [2.0 * np.sin(P[:, 0] / 40.0), 1.5 * np.cos(P[:, 1] / 50.0) - 1.5, 3.0 * np.exp(-(P[:, 0] ** 2) / 2000.0)],
        axis=1,
    )[None]


class CaptureCase:
    """Files of a small capture case plus the truth used to make them."""

    def __init__(self, root: Path, *, n_frames: int = 40, head_motion: bool = False, seed: int = 0) -> None:
        rng = np.random.default_rng(seed)
        self.V, self.F = curved_grid()
        interior = np.flatnonzero((np.abs(self.V[:, 0]) < 55) & (np.abs(self.V[:, 1]) < 55))
        self.marker_vertices = rng.choice(interior, 30, replace=False)
        self.labels = [f"M{i:02d}" for i in range(30)]
        t = np.linspace(0, 1, n_frames)
        self.truth = self.V[None] + smooth_field(self.V, t)  # (T, n, 3), scan frame
        face_markers = self.truth[:, self.marker_vertices]
        # head band: 4 rigid markers behind the sheet
        band = np.array([[-50.0, 60.0, -40.0], [50.0, 60.0, -40.0], [-50.0, -60.0, -40.0], [50.0, -60.0, -40.0]])
        markers = np.concatenate([face_markers, np.broadcast_to(band, (n_frames, 4, 3))], axis=1)
        if head_motion:
            rot = Rotation.from_rotvec(np.outer(np.sin(2 * np.pi * t), [0.03, 0.05, -0.02])).as_matrix()
            markers = np.einsum("tij,tkj->tki", rot, markers) + np.outer(np.sin(2 * np.pi * t), [3.0, -2.0, 1.0])[:, None]
        # a different rigid frame for the mocap system
        self.mocap_R = Rotation.from_rotvec([0.2, -0.4, 0.1]).as_matrix()
        self.mocap_t = np.array([100.0, 1400.0, -30.0])
        markers = markers @ self.mocap_R.T + self.mocap_t
        self.take = MarkerSequence(markers, tuple(self.labels + ["HB0", "HB1", "HB2", "HB3"]), rate=60.0)
        self.mesh = Mesh(self.V, self.F)
        self.root = root
        self.scan_path = root / "scan.obj"
        self.markers_path = root / "take.c3d"
        self.map_path = root / "map.json"
        write_mesh(self.mesh, self.scan_path)
        write_markers(self.take, self.markers_path)
        self.map_path.write_text(json.dumps({s: int(v) for s, v in zip(self.labels, self.marker_vertices)}))
        truth_path = root / "truth.npz"
        np.savez(truth_path, vertices=self.truth.astype(np.float32), units=np.array("mm"))
        self.truth_path = truth_path
