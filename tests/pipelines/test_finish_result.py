"""A job's result folder finished: the exports and pages written in staging, then listed and renamed."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np

from facecap.io import PerformanceWriter
from facecap.pipelines.finish_result import finish_result
from facecap.structures import Mesh


def test_import_writers_imports_each_exports_modules_and_nothing_before():
    # a fresh interpreter: importing the job's module loads neither usd-core nor matplotlib; import_writers loads
    # what the USD export and the report page will need
    script = (
        "import sys\n"
        "from facecap.pipelines.finish_result import import_writers\n"
        "assert 'pxr.UsdSkel' not in sys.modules and 'matplotlib.figure' not in sys.modules\n"
        "import_writers(['usd'])\n"
        "assert {'pxr.UsdSkel', 'facecap.io.write_usd_blendshapes', 'matplotlib.figure',\n        'facecap.pipelines.export_result'} <= set(sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_the_exports_and_the_pages_are_in_the_listed_files(tmp_path, monkeypatch):
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    mesh = Mesh(V, np.array([[0, 1, 2], [1, 3, 2]]), source_unit="mm")
    frames = (V[None] + np.arange(3)[:, None, None] * np.array([0.0, 0, 0.1])).astype(np.float32)  # it moves
    (tmp_path / "take.c3d").write_bytes(b"")
    monkeypatch.chdir(tmp_path)
    with PerformanceWriter(tmp_path / "res", mesh=mesh, rate=30.0, n_frames=3, exports=["gltf", "mdd"]) as writer:
        writer.write_frames(0, frames)
        out = finish_result(writer, {"source_files": {"markers": "take.c3d"}})
    info = json.loads((out / "performance.json").read_text())
    assert {"performance.glb", "performance.mdd", "performance_rest.obj", "review.html", "report.html"} <= set(info["files"])
    assert info["files"] == {p: (out / p).stat().st_size for p in info["files"]}
    assert set(info["exports_report"]) == {"gltf", "mdd"} and info["exports"] == ["gltf", "mdd"]
    assert ": res</title>" in (out / "report.html").read_text()  # the folder, not its staging name
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res", "take.c3d"]
