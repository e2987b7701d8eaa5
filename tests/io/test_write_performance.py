"""The output folder's writer: the rig beside the caller, an earlier result, the paths it records."""

from __future__ import annotations


def test_the_rig_written_beside_the_caller_is_on_disk_at_finish_and_its_failure_loses_nothing(tmp_path, monkeypatch):
    import numpy as np
    import pytest

    import facecap.io.result_rig as result_rig
    from facecap.io import PerformanceWriter, ResultRig, read_result
    from facecap.structures import Mesh

    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    mesh = Mesh(V, np.array([[0, 1, 2], [1, 3, 2]]), source_unit="mm")
    rng = np.random.default_rng(0)
    rig = ResultRig(V.astype(np.float32), rng.random((2, 4)).astype(np.float32),
                    rng.normal(size=(5, 2, 3)).astype(np.float32))
    with PerformanceWriter(tmp_path / "ok", mesh=mesh, rate=60.0, n_frames=5, vertices=False) as writer:
        writer.write_rig(rig)
        writer.finish({})
    np.testing.assert_allclose(read_result(tmp_path / "ok").rig.frames(), rig.frames(), atol=1e-6)

    def full_disk(folder, rig):
        raise OSError("No space left on device")

    monkeypatch.setattr(result_rig, "write_rig", full_disk)
    with pytest.raises(OSError, match="No space"):
        with PerformanceWriter(tmp_path / "full", mesh=mesh, rate=60.0, n_frames=5, vertices=False) as writer:
            writer.write_rig(rig)
            writer.finish({})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ok"]  # nothing that looks finished, no staging left


def _square(tmp_path):
    import numpy as np

    from facecap.structures import Mesh

    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    return Mesh(V, np.array([[0, 1, 2], [1, 3, 2]]), source_unit="mm"), np.tile(V.astype(np.float32), (3, 1, 1))


def _write(out, mesh, frames, metadata=None, **options):
    from facecap.io import PerformanceWriter

    with PerformanceWriter(out, mesh=mesh, rate=30.0, n_frames=3, **options) as writer:
        writer.write_frames(0, frames)
        return writer.finish(metadata or {})


def test_an_earlier_result_is_replaced_only_with_overwrite(tmp_path):
    import numpy as np
    import pytest

    from facecap.errors import InputError
    from facecap.io.write_performance import check_result_destination

    mesh, frames = _square(tmp_path)
    out = _write(tmp_path / "out", mesh, frames)
    (out / "review.html").write_text("made since")
    with pytest.raises(InputError, match="pass --overwrite") as info:
        check_result_destination(out)
    assert info.value.path == str(out)
    with pytest.raises(InputError, match="pass --overwrite"):
        _write(out, mesh, frames + 1)
    assert (out / "review.html").read_text() == "made since"
    np.testing.assert_array_equal(np.load(out / "vertices.npy"), frames)
    _write(out, mesh, frames + 1, overwrite=True)
    np.testing.assert_array_equal(np.load(out / "vertices.npy"), frames + 1)
    assert not (out / "review.html").exists() and sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_source_files_are_recorded_final(tmp_path, monkeypatch):
    import json

    mesh, frames = _square(tmp_path)
    (tmp_path / "take.c3d").write_bytes(b"")
    monkeypatch.chdir(tmp_path)
    out = _write(tmp_path / "res", mesh, frames, {"source_files": {
        "markers": "take.c3d", "scan": None, "footage": [tmp_path / "a", "b"], "report": tmp_path / "res" / "x.json"}})
    info = json.loads((out / "performance.json").read_text())
    # relative to the working folder given: recorded absolute; inside the result: relative to it; None kept
    assert info["source_files"] == {"markers": str(tmp_path / "take.c3d"), "scan": None,
                                    "footage": [str(tmp_path / "a"), str(tmp_path / "b")], "report": "x.json"}


def test_finish_writes_the_metadata_once_and_lists_every_file(tmp_path):
    import json

    import pytest

    from facecap.errors import InputError
    from facecap.io import PerformanceWriter

    mesh, frames = _square(tmp_path)
    with PerformanceWriter(tmp_path / "res", mesh=mesh, rate=30.0, n_frames=3) as writer:
        writer.write_frames(0, frames)
        staging = writer.write_metadata({"method": "test"})
        (staging / "extra.txt").write_text("added between the two")
        with pytest.raises(InputError, match="written already"):
            writer.write_metadata({})
        out = writer.finish()
    info = json.loads((out / "performance.json").read_text())
    assert info["method"] == "test" and info["files"]["extra.txt"] == 21
    assert set(info["files"]) == {"extra.txt", "faces.npy", "mesh.npz", "vertices.npy"}
