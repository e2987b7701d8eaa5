"""The layer order of docs/architecture.md, checked on every import of ``src/facecap``.

The imports are read with ``ast`` (those inside functions count too), never run. Three rules:
no arrow from a lower layer to a higher one, no circle between subpackages, and no module
importing another module's private name. A circle through two layers holds an upward arrow and is
reported as that arrow; circles are looked for inside each layer. What breaks them today is listed in ``KNOWN_DEBT``,
each with the step that removes it; a new break fails, and so does a listed one that is gone
(take it off the list).
"""

from __future__ import annotations

import ast
import re
from collections import defaultdict
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "facecap"
ARCHITECTURE = ROOT / "docs" / "architecture.md"

KNOWN_DEBT: set[str] = set()  # every break listed here was removed by issue 29; keep it empty


class Import(NamedTuple):
    importer: str  # dotted module name
    target: str  # dotted module name imported from
    names: tuple[str, ...]  # names taken from it (empty for ``import x``)
    line: int


def read_layer_order(text: str) -> list[list[str]]:
    """The layers, lowest first, from the page's ``Layer order, lowest first:`` line."""
    match = re.search(r"^Layer order, lowest first: (.+)$", text, flags=re.MULTILINE)
    if match is None:
        raise AssertionError("docs/architecture.md has no 'Layer order, lowest first:' line")
    return [group.split() for group in re.findall(r"`([^`]+)`", match.group(1))]


def module_name(path: Path, root: Path) -> str:
    parts = path.relative_to(root.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def read_imports(root: Path) -> list[Import]:
    """Every ``import`` and ``from ... import`` of the package under ``root``, relative ones resolved."""
    found = []
    for path in sorted(root.rglob("*.py")):
        name = module_name(path, root)
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
            if isinstance(node, ast.Import):
                found.extend(Import(name, alias.name, (), node.lineno) for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                found.append(Import(name, target, tuple(alias.name for alias in node.names), node.lineno))
    return found


def subpackage(module: str, root_name: str) -> str | None:
    """``facecap.deform.thin_shell`` -> ``deform``; ``facecap.cli`` -> ``cli``; the package root -> None."""
    parts = module.split(".")
    return parts[1] if parts[0] == root_name and len(parts) > 1 else None


def layer_breaks(root: Path, layers: list[list[str]]) -> dict[str, str]:
    """Each break of the three rules -> where it is (``file:line`` of one import that makes it)."""
    rank = {name: level for level, group in enumerate(layers) for name in group}
    root_name = root.name
    modules = {module_name(p, root) for p in root.rglob("*.py")}
    unplaced = sorted({s for m in modules if (s := subpackage(m, root_name)) is not None} - set(rank))
    if unplaced:
        raise AssertionError(f"subpackages in no layer of docs/architecture.md: {unplaced}")
    breaks: dict[str, str] = {}
    edges: dict[tuple[str, str], str] = {}
    for imp in read_imports(root):
        here = f"{imp.importer}:{imp.line}"
        source, target = subpackage(imp.importer, root_name), subpackage(imp.target, root_name)
        if source is not None and target is not None and source != target:
            if rank[target] == rank[source]:  # a circle through layers holds an upward arrow, reported as such
                edges.setdefault((source, target), here)
            if rank[target] > rank[source]:
                breaks.setdefault(f"arrow {source} -> {target}", here)
        if imp.target.split(".")[0] == root_name and imp.target != imp.importer:
            for name in imp.names:
                private = name.startswith("_") and not name.startswith("__")
                if private and f"{imp.target}.{name}" not in modules:  # a private module itself is fine
                    breaks.setdefault(f"private {imp.importer} <- {imp.target}", here)
    names = sorted(rank)
    index = {name: k for k, name in enumerate(names)}
    graph = sp.coo_matrix((np.ones(len(edges)), ([index[a] for a, _ in edges], [index[b] for _, b in edges])),
                          shape=(len(names), len(names)))
    _, component = connected_components(graph, directed=True, connection="strong")
    members = defaultdict(list)
    for name in names:
        members[component[index[name]]].append(name)
    for group in members.values():
        if len(group) > 1:
            where = next(w for (a, b), w in edges.items() if a in group and b in group)
            breaks[f"circle {' '.join(sorted(group))}"] = where
    return breaks


def test_the_package_keeps_its_layers() -> None:
    breaks = layer_breaks(PACKAGE, read_layer_order(ARCHITECTURE.read_text(encoding="utf-8")))
    new = {b: w for b, w in breaks.items() if b not in KNOWN_DEBT}
    gone = KNOWN_DEBT - set(breaks)
    assert not new, f"imports against docs/architecture.md's layers: {new}"
    assert not gone, f"no longer broken, take them off KNOWN_DEBT: {sorted(gone)}"


def _write(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


def test_the_checker_finds_an_upward_arrow_a_circle_and_a_private_name(tmp_path: Path) -> None:
    # a package built to break each rule once, at known lines
    root = _write(tmp_path / "pkg", {
        "__init__.py": "",
        "low/__init__.py": "",
        "low/base.py": "from ..high.job import run\n",  # line 1: upward
        "high/__init__.py": "",
        "high/job.py": "import os\n\nfrom ..low import base\nfrom ..low.base import _helper\n",
        "mid/__init__.py": "from ..side import thing\n",
        "side/__init__.py": "from pkg.mid import other\n",  # absolute import closing a circle
    })
    layers = [["low"], ["mid", "side"], ["high"]]
    breaks = layer_breaks(root, layers)
    # low and high import each other too: that circle is the upward arrow, reported once as such
    assert set(breaks) == {"arrow low -> high", "private pkg.high.job <- pkg.low.base", "circle mid side"}
    assert breaks["arrow low -> high"] == "pkg.low.base:1"
    assert breaks["private pkg.high.job <- pkg.low.base"] == "pkg.high.job:4"
    assert breaks["circle mid side"] in {"pkg.mid:1", "pkg.side:1"}
    with pytest.raises(AssertionError, match="no layer"):
        layer_breaks(root, [["low"], ["high"]])


def test_the_layer_order_is_read_from_the_page() -> None:
    layers = read_layer_order("x\nLayer order, lowest first: `a b` < `c` < `d e f`\n")
    assert layers == [["a", "b"], ["c"], ["d", "e", "f"]]
