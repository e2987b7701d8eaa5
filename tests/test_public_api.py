"""One obvious import per concept: every subpackage re-exports its modules' public names.

Generic on purpose: a module added to any subpackage is checked as soon as it
exists. What a new public module needs (also in the report of issue 9):

1. an ``__all__`` listing its public names;
2. its subpackage's ``__init__.py`` importing every one of those names and
   listing them in the subpackage's ``__all__``;
3. its file name (``new_module.py``) mentioned in the subpackage's docstring,
   where the subpackage says which module holds what.
"""

from __future__ import annotations

import ast
import importlib
import pkgutil
import re
import subprocess
import sys
from pathlib import Path

import pytest

import facecap

ROOT = Path(__file__).resolve().parents[1]


def _subpackages() -> list[str]:
    return sorted(
        info.name for info in pkgutil.walk_packages(facecap.__path__, prefix="facecap.") if info.ispkg
    )


def _public_modules(package: str) -> list[str]:
    pkg = importlib.import_module(package)
    return sorted(
        f"{package}.{info.name}"
        for info in pkgutil.iter_modules(pkg.__path__)
        if not info.ispkg and not info.name.startswith("_")
    )


SUBPACKAGES = _subpackages()


def test_the_pipeline_stages_are_subpackages() -> None:
    expected = {"io", "mesh", "markers", "deform", "blendshapes", "registration", "synth", "report"}
    assert expected <= {name.split(".")[1] for name in SUBPACKAGES}


@pytest.mark.parametrize("package", SUBPACKAGES)
def test_subpackage_all_names_exist_and_star_import(package: str) -> None:
    pkg = importlib.import_module(package)
    names = getattr(pkg, "__all__", None)
    assert isinstance(names, list) and names, f"{package} has no __all__"
    assert len(set(names)) == len(names), f"{package}.__all__ repeats a name"
    missing = [n for n in names if not hasattr(pkg, n)]
    assert not missing, f"{package}.__all__ names what it does not define: {missing}"
    namespace: dict[str, object] = {}
    exec(f"from {package} import *", namespace)  # noqa: S102
    assert set(names) <= set(namespace)
    for name in names:  # the function, not the module of the same name
        assert not isinstance(getattr(pkg, name), type(pkg)), f"{package}.{name} is a module"


@pytest.mark.parametrize("package", SUBPACKAGES)
def test_every_public_module_is_reexported(package: str) -> None:
    pkg = importlib.import_module(package)
    exported = set(pkg.__all__)
    doc = pkg.__doc__ or ""
    for module_name in _public_modules(package):
        module = importlib.import_module(module_name)
        short = module_name.rsplit(".", 1)[1]
        names = getattr(module, "__all__", None)
        assert isinstance(names, list), f"{module_name} has no __all__ (list its public names)"
        forgotten = [n for n in names if n not in exported]
        assert not forgotten, f"{package}/__init__.py does not re-export {forgotten} from {short}.py"
        for name in names:
            assert getattr(pkg, name) is getattr(module, name), f"{package}.{name} is not {module_name}.{name}"
        assert f"{short}.py" in doc, f"{package}'s docstring does not say what {short}.py holds"


def test_top_level_exports() -> None:
    names = facecap.__all__
    assert len(set(names)) == len(names)
    assert all(hasattr(facecap, n) for n in names)


def _run(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300)


def test_import_facecap_stays_light() -> None:
    """``import facecap`` loads no subpackage (and so none of numba, matplotlib, libigl, OpenCV)."""
    out = _run(
        "import sys, facecap\n"
        "print(' '.join(m for m in sys.modules if m.startswith('facecap.') or m in "
        "('numba', 'matplotlib', 'igl', 'cv2', 'pxr', 'trimesh')))"
    )
    assert out.returncode == 0, out.stderr
    loaded = out.stdout.split()
    heavy = [m for m in loaded if m.count(".") == 0 or m.split(".")[1] in {p.split(".")[1] for p in SUBPACKAGES}]
    assert not heavy, f"import facecap loads {heavy}"


def test_no_import_cycles() -> None:
    """Every module imports on its own, first, in a fresh facecap (a cycle fails for some order)."""
    modules = sorted(info.name for info in pkgutil.walk_packages(facecap.__path__, prefix="facecap."))
    code = (
        "import importlib, sys\n"
        f"failed = []\n"
        f"for name in {modules!r}:\n"
        "    for m in [m for m in sys.modules if m == 'facecap' or m.startswith('facecap.')]:\n"
        "        del sys.modules[m]\n"
        "    try:\n"
        "        importlib.import_module(name)\n"
        "    except Exception as exc:\n"
        "        failed.append(f'{name}: {type(exc).__name__}: {exc}')\n"
        "print('\\n'.join(failed))\n"
    )
    out = _run(code)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "", out.stdout


def _python_blocks(path: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", path.read_text(encoding="utf-8"), flags=re.S)


DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda p: p.name)
def test_documented_imports_run(document: Path) -> None:
    """The import lines of every python block in the README and docs execute."""
    imports = []
    for block in _python_blocks(document):
        tree = ast.parse(block)
        imports += [node for node in ast.walk(tree) if isinstance(node, (ast.Import, ast.ImportFrom))]
    if document.name == "README.md":
        assert imports, "the README's Library section shows no import"
    module = ast.Module(body=imports, type_ignores=[])
    exec(compile(module, str(document), "exec"), {})  # noqa: S102
