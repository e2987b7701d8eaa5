"""The Khronos glTF validator and meshoptimizer's reference decoder, for the glTF tests.

Both are npm packages pinned in ``tools/gltf-validator/package-lock.json``
(``gltf-validator`` 2.0.0-dev.3.10, ``meshoptimizer`` 1.3.0). The first call
installs them with ``npm ci`` when ``tools/gltf-validator/node_modules`` is
missing (the test path installs what it needs; nothing is skipped), then each
check runs a small committed Node script on the file.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pygltflib

from tool_install import install_lock

ROOT = Path(__file__).resolve().parents[1]
TOOLS = ROOT / "tools" / "gltf-validator"


def _ensure_installed() -> None:
    """Run ``npm ci`` once if the pinned packages are not installed yet (one process at a time)."""
    with install_lock("gltf-validator-npm"):
        wanted = [TOOLS / "node_modules" / name / "package.json" for name in ("gltf-validator", "meshoptimizer")]
        if all(path.exists() for path in wanted):
            return
        npm = shutil.which("npm")
        if npm is None:
            raise RuntimeError("npm is needed to install the glTF validator (apt-get install npm)")
        subprocess.run(
            [npm, "ci", "--prefix", str(TOOLS), "--no-audit", "--no-fund"],
            check=True, capture_output=True, text=True, timeout=600,
        )


def _node(script: str, *args: str) -> str:
    _ensure_installed()
    node = shutil.which("node")
    if node is None:
        raise RuntimeError("node is needed to run the glTF validator (apt-get install nodejs)")
    done = subprocess.run(
        [node, str(TOOLS / script), *args], capture_output=True, text=True, timeout=300, cwd=TOOLS
    )
    if done.returncode != 0:
        raise RuntimeError(f"{script} failed:\n{done.stderr}")
    return done.stdout


def validate_gltf(path: str | Path) -> dict:
    """The Khronos validator's JSON report on ``path`` (``report['issues']['numErrors']`` etc.)."""
    return json.loads(_node("validate.mjs", str(path)))


def issue_summary(report: dict, severity: int) -> list[str]:
    """``'CODE at POINTER: message'`` for each issue of ``severity`` (0 error, 1 warning, 2 info, 3 hint)."""
    return [
        f"{m['code']} at {m.get('pointer', '')}: {m['message']}"
        for m in report["issues"]["messages"]
        if m["severity"] == severity
    ]


def decode_meshopt(path: str | Path, out_dir: str | Path) -> list[int]:
    """Decode ``path``'s EXT_meshopt_compression bufferViews into ``out_dir/bufferView_<i>.bin``.

    Uses meshoptimizer's own JavaScript decoder (not the encoder's binding), so
    a round trip through it checks the bytes against the reference. Returns
    the indices of the decoded bufferViews.
    """
    return json.loads(_node("decode_meshopt.mjs", str(path), str(out_dir)))["decoded"]


def assert_valid(path: Path) -> dict:
    """Zero errors and zero warnings from the Khronos validator (infos listed in the failure message)."""
    report = validate_gltf(path)
    errors, warnings = issue_summary(report, 0), issue_summary(report, 1)
    assert report["issues"]["numErrors"] == 0, errors
    assert report["issues"]["numWarnings"] == 0, warnings
    return report


COMPONENT_DTYPES = {5126: np.float32, 5125: np.uint32, 5123: np.uint16}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def read_accessor(gltf: pygltflib.GLTF2, blob: bytes, index: int) -> np.ndarray:
    accessor = gltf.accessors[index]
    view = gltf.bufferViews[accessor.bufferView]
    dtype = np.dtype(COMPONENT_DTYPES[accessor.componentType])
    width = _WIDTH[accessor.type]
    start = (view.byteOffset or 0) + (accessor.byteOffset or 0)
    data = np.frombuffer(blob, dtype=dtype, count=accessor.count * width, offset=start)
    return data.reshape(accessor.count, width) if width > 1 else data


def load(path: Path) -> tuple[pygltflib.GLTF2, bytes]:
    gltf = pygltflib.GLTF2().load_binary(str(path))
    return gltf, gltf.binary_blob()
