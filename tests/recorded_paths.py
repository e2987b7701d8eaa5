"""Every path a written folder records is final: no staging name, and the file is there.

Importable as ``recorded_paths`` (``tests/`` is on the path), for the tests of every job that
writes a folder (``tests/test_cli.py``, ``tests/pipelines/test_run_demo.py``).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any, Iterator

_FILE_SUFFIX = re.compile(r"\.(obj|ply|glb|c3d|trc|csv|json|npz|npy|png|usdc|abc|mdd|pc2|yml|yaml|html)$", re.I)


_NOT_PATHS = {"format"}
"""Keys whose values are names with a slash, not paths (``"facecap-anatomy/1"``)."""


def _strings(value: Any) -> Iterator[str]:
    """Every string value of a JSON document, and the keys of ``files`` (``performance.json`` lists paths as keys)."""
    if isinstance(value, str):
        yield value
    elif isinstance(value, dict):
        for key, item in value.items():
            if key == "files" and isinstance(item, dict):
                yield from item
            if key not in _NOT_PATHS:
                yield from _strings(item)
    elif isinstance(value, list):
        for item in value:
            yield from _strings(item)


def _is_path(text: str) -> bool:
    """A recorded path, not a label or a sentence: one word, absolute, with a folder, or a file name."""
    return bool(text) and not any(c.isspace() for c in text) and (
        text.startswith("/") or "/" in text or bool(_FILE_SUFFIX.search(text)))


def assert_recorded_paths_are_final(root: Path) -> int:
    """Check every JSON and HTML file under ``root``; returns how many recorded paths were checked.

    No string in any of them holds a staging name (``.partial-``). Every path a JSON file records
    exists: absolute ones as they are, relative ones from the file's own folder (how
    :func:`facecap.io.atomic_write.recorded_path` records them).
    """
    checked = 0
    for path in sorted(root.rglob("*")):
        if path.suffix == ".html":
            text = path.read_text(encoding="utf-8")
            assert ".partial-" not in text, f"{path}: a staging name: ...{text[text.index('.partial-') - 80:][:160]}"
        elif path.suffix == ".json":
            for text in _strings(json.loads(path.read_text())):
                assert ".partial-" not in text, f"{path}: a staging name: {text}"
                if _is_path(text):
                    recorded = Path(text) if Path(text).is_absolute() else path.parent / text
                    assert recorded.exists(), f"{path}: records {text}, which does not exist"
                    checked += 1
    return checked
