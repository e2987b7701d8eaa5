"""The compact form against ``vertices.npy``: largest difference in mm, float32 and int16 (issue 12's exactness bar).

Cases: the bundled sample as ``facecap demo`` runs it (``animate`` on the generated take, the scan
workflow's ``blend``, ``animate`` on the real AnimFace take), and a 100k-vertex case
(``bench_thin_shell``'s 100k mesh, 90 markers, 600 frames) for ``animate`` and for ``blend``
(20 bases: the rest shape moved by smooth random fields, NNLS-like weights). For each, the float32 rig
against ``vertices.npy`` of the same run, and the int16 rig against its stated bound.

    python benchmarks/bench_rig_exactness.py
"""

from __future__ import annotations

import json
import shutil
import sys
import tempfile
import warnings
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_compact_output import _case  # noqa: E402


def _compare(folder: Path) -> dict[str, Any]:
    from facecap.io import read_result

    result = read_result(folder)
    vertices = np.load(folder / "vertices.npy", mmap_mode="r")
    worst = 0.0
    q = result.rig.quantized()
    worst_q = 0.0
    for start in range(0, result.n_frames, 64):
        stop = min(start + 64, result.n_frames)
        v = np.asarray(vertices[start:stop], dtype=np.float64)
        worst = max(worst, float(np.abs(result.rig.frames(start, stop) - v).max()))
        worst_q = max(worst_q, float(np.abs(q.frames(start, stop) - v).max()))
    scale = result.mm_per_unit
    return {"frames": result.n_frames, "vertices": result.n_vertices, "kind": result.rig.kind,
            "float32_max_mm": worst * scale, "int16_max_mm": worst_q * scale,
            "int16_bound_mm": q.error_bound * scale, "int16_within_bound": worst_q <= q.error_bound + 1e-5,
            "max_motion_mm": float(np.abs(np.asarray(vertices[-1]) - result.rig.rest).max() * scale)}


def main() -> None:
    from facecap.pipelines import animate_scan, run_demo, write_blended_performance

    work = Path(tempfile.mkdtemp(prefix="rig_exactness_"))
    out: dict[str, Any] = {}
    try:
        run_demo(work / "demo", n_frames=300, progress=False)
        out["sample_animate"] = _compare(work / "demo" / "animation")
        out["sample_blend"] = _compare(work / "demo" / "scans" / "blend")
        out["sample_animface"] = _compare(work / "demo" / "animface")

        scan, take, corr = _case("100k", 600, work)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            animate_scan(scan, take, corr, work / "a100k", progress=False)
        out["100k_animate"] = _compare(work / "a100k")

        rng = np.random.default_rng(0)
        V = scan.vertices
        fields = [np.sin(V[:, [0]] / rng.uniform(10, 60)) * rng.normal(size=3) * 3.0
                  + np.cos(V[:, [1]] / rng.uniform(10, 60)) * rng.normal(size=3) * 2.0 for _ in range(20)]
        bases = V[None] + np.stack(fields)
        weights = rng.dirichlet(np.full(20, 0.3), size=600)
        write_blended_performance(work / "b100k", scan, bases, weights, rate=60.0, progress=False)
        out["100k_blend"] = _compare(work / "b100k")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
