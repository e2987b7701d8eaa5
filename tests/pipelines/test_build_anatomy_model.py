"""Tests for facecap/pipelines/build_anatomy_model.py: the model folder's assembly (the destination refused
first, the model and its picture appearing together or not at all). The build itself is the anatomy
package's (tests/test_anatomy_build.py); the command end to end is tests/test_cli_anatomy_and_removal.py."""

import importlib

import pytest

from facecap.errors import FacecapError
from facecap.io import write_mesh
from facecap.pipelines import build_anatomy_model
from facecap.structures import Mesh

job = importlib.import_module("facecap.pipelines.build_anatomy_model")


class _Model:
    def save(self, folder):
        (folder / "anatomy.npz").write_bytes(b"model")
        (folder / "anatomy.json").write_text("{}")


@pytest.fixture
def scan(tmp_path):
    path = tmp_path / "scan.obj"
    write_mesh(Mesh([[0.0, 0, 0], [10, 0, 0], [0, 10, 0]], [[0, 1, 2]]), path)
    return path


def test_the_folder_holds_the_model_and_its_picture(scan, tmp_path, monkeypatch):
    asked = {}

    def build(mesh, landmarks=None, n_tets=0, progress=True):
        asked.update(vertices=mesh.n_vertices, landmarks=landmarks, n_tets=n_tets, progress=progress)
        return _Model()

    monkeypatch.setattr(job, "build_anatomy", build)
    monkeypatch.setattr(job, "render_anatomy_layout", lambda model, path: path.write_bytes(b"png"))
    out = tmp_path / "model"
    assert isinstance(build_anatomy_model(scan, out, n_tets=1234, landmarks="marks.json", progress=False), _Model)
    assert asked == {"vertices": 3, "landmarks": "marks.json", "n_tets": 1234, "progress": False}
    assert sorted(p.name for p in out.iterdir()) == ["anatomy.json", "anatomy.npz", "layout.png"]
    # a second build into it is refused before the scan is read, unless overwrite
    with pytest.raises(FacecapError, match="pass --overwrite"):
        build_anatomy_model(tmp_path / "missing.obj", out)
    build_anatomy_model(scan, out, overwrite=True)
    assert sorted(p.name for p in out.iterdir()) == ["anatomy.json", "anatomy.npz", "layout.png"]


def test_a_failed_picture_leaves_no_model(scan, tmp_path, monkeypatch):
    def fail(model, path):
        raise RuntimeError("no picture")

    monkeypatch.setattr(job, "build_anatomy", lambda mesh, **options: _Model())
    monkeypatch.setattr(job, "render_anatomy_layout", fail)
    with pytest.raises(RuntimeError, match="no picture"):
        build_anatomy_model(scan, tmp_path / "model")
    assert [p.name for p in tmp_path.iterdir()] == ["scan.obj"]
