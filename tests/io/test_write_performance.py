"""The output folder's writer: what it imports ahead of time."""

from __future__ import annotations

import subprocess
import sys


def test_import_writers_imports_each_exports_modules_and_nothing_before():
    # a fresh interpreter: importing facecap.io loads neither usd-core nor matplotlib; import_writers loads
    # what the USD export and the report page will need
    script = (
        "import sys\n"
        "from facecap.io import import_writers\n"
        "assert 'pxr.UsdSkel' not in sys.modules and 'matplotlib.figure' not in sys.modules\n"
        "import_writers(['usd'])\n"
        "assert {'pxr.UsdSkel', 'facecap.io.write_usd_blendshapes', 'matplotlib.figure'} <= set(sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


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
