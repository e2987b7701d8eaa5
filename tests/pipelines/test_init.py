"""Tests for facecap/pipelines/__init__.py: jobs imported when first used, their names bound to the functions."""

import subprocess
import sys


def _run(code: str) -> list[str]:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300)
    return out.stdout.split("\n")


def test_one_job_loads_neither_the_other_jobs_nor_their_solvers():
    lines = _run(
        "import sys\n"
        "from facecap.pipelines import animate_scan\n"
        "print(sorted(m for m in sys.modules if m.startswith('facecap.pipelines.')))\n"
        "print([m for m in ('facecap.anatomy', 'facecap.muscles', 'trimesh') if m in sys.modules])\n"
    )
    # and the jobs' shared end, with the exports it makes
    assert lines[0] == "['facecap.pipelines.animate_scan', 'facecap.pipelines.export_result', 'facecap.pipelines.finish_result']"
    assert lines[1] == "[]"


def test_a_jobs_name_is_its_function_however_its_module_was_imported():
    lines = _run(
        "import importlib, types\n"
        "import facecap.pipelines as jobs\n"
        "import facecap.pipelines.blend_take\n"  # the submodule first: the import system binds it on the package
        "from facecap.pipelines.edit_muscles import EDIT_METHOD\n"
        "print(isinstance(jobs.blend_take, types.FunctionType), isinstance(jobs.edit_muscles, types.FunctionType))\n"
        "module = importlib.import_module('facecap.pipelines.blend_take')\n"
        "print(jobs.blend_take is module.blend_take, jobs.EDIT_METHOD == EDIT_METHOD)\n"
        "print(all(hasattr(jobs, name) for name in jobs.__all__), 'animate_scan' in dir(jobs))\n"
    )
    assert lines[:3] == ["True True", "True True", "True True"]
