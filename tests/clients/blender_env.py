"""Blender as a Python module (``bpy``) in its own cached virtual environment.

The client check runs facecap's exports through Blender's own importers, so it
needs Blender. The ``bpy`` wheel is Blender built as a Python module; it
bundles its USD, Alembic and glTF importers. It cannot share facecap's
environment: ``bpy`` 5.0.1 is built for CPython 3.11 only and pins
``numpy < 2``. So it lives in a virtual environment of its own, created the
first time a test asks for it and reused afterwards:

    ``<cache>/blender-5.0.1/`` with ``<cache>`` = ``$FACECAP_TEST_CACHE``, else
    ``$XDG_CACHE_HOME/facecap-tests``, else ``~/.cache/facecap-tests``.

A finished environment holds ``facecap-ready.json`` (written last, after a
successful import of ``bpy``); a folder without it is a failed or interrupted
install and is rebuilt. A lock file serialises concurrent builds. Nothing
here skips: when the install fails, :class:`BlenderEnvironmentError` carries
pip's output and the test that asked fails with it.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

from tool_install import cache_root, install_lock

BLENDER_VERSION = "5.0.1"
"""The ``bpy`` release the client check runs (the last one built for CPython 3.11)."""

BLENDER_PYTHON = (3, 11)
"""The CPython version the ``bpy`` wheel is built for."""

REQUIREMENTS = (f"bpy=={BLENDER_VERSION}", "numpy<2")
"""What the environment installs: bpy pins numpy below 2 (its own C API)."""

INSTALL_TIMEOUT_S = 1800
"""Longest the pip install may take (a clean cache downloads ~374 MB)."""

_READY = "facecap-ready.json"


class BlenderEnvironmentError(RuntimeError):
    """The Blender environment could not be built or does not work; the message holds the output."""


def environment_dir() -> Path:
    """The virtual environment of this Blender version (keyed by version)."""
    return cache_root() / f"blender-{BLENDER_VERSION}"


def _venv_python(env: Path) -> Path:
    return env / "bin" / "python"


def _base_interpreter() -> str:
    """A CPython 3.11 to build the environment from: this one if it is 3.11, else ``python3.11``."""
    if sys.version_info[:2] == BLENDER_PYTHON:
        return sys.executable
    name = "python{}.{}".format(*BLENDER_PYTHON)
    found = shutil.which(name)
    if found is None:
        raise BlenderEnvironmentError(
            f"bpy {BLENDER_VERSION} needs CPython {name[6:]} (its only wheels are cp311); this interpreter "
            f"is {sys.version.split()[0]} and no {name} is on PATH: install {name} (with its venv module)"
        )
    return found


def _run(cmd: list[str], *, timeout: float) -> str:
    """Run ``cmd``; return its output, or raise with the output when it fails."""
    try:
        done = subprocess.run(
            cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=timeout, check=False
        )
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout.decode(errors="replace") if isinstance(exc.stdout, bytes) else (exc.stdout or "")
        raise BlenderEnvironmentError(f"{' '.join(cmd)} ran past {timeout:.0f} s:\n{out}") from exc
    if done.returncode != 0:
        raise BlenderEnvironmentError(f"{' '.join(cmd)} exited with {done.returncode}:\n{done.stdout}")
    return done.stdout


def _works(python: Path) -> bool:
    """True if ``python`` imports this Blender version's ``bpy`` and numpy."""
    if not python.exists():
        return False
    check = (
        "import bpy, numpy; "
        f"assert bpy.app.version_string == {BLENDER_VERSION!r}, bpy.app.version_string; "
        "assert bpy.app.build_options.usd and bpy.app.build_options.alembic"
    )
    try:
        _run([str(python), "-c", check], timeout=120)
    except BlenderEnvironmentError:
        return False
    return True


def blender_python() -> Path:
    """The interpreter of the Blender environment, built first if missing or broken.

    Returns
    -------
    pathlib.Path
        ``<environment>/bin/python``: run Blender scripts with it.

    Raises
    ------
    BlenderEnvironmentError
        If no CPython 3.11 is available, or venv/pip fail (with their output),
        or the installed ``bpy`` does not import.
    """
    env = environment_dir()
    python = _venv_python(env)
    if (env / _READY).exists() and _works(python):
        return python
    with install_lock(env.name):  # another test run or worker may be building it right now
        if (env / _READY).exists() and _works(python):
            return python
        if env.exists():
            shutil.rmtree(env)  # a broken or unfinished install: start again
        started = time.monotonic()
        log = _run([_base_interpreter(), "-m", "venv", str(env)], timeout=300)
        log += _run(
            [str(python), "-m", "pip", "install", "--no-input", "--progress-bar", "off", *REQUIREMENTS],
            timeout=INSTALL_TIMEOUT_S,
        )
        if not _works(python):
            raise BlenderEnvironmentError(
                f"bpy {BLENDER_VERSION} installed in {env} but does not import; pip said:\n{log}"
            )
        (env / _READY).write_text(
            json.dumps(
                {"bpy": BLENDER_VERSION, "requirements": list(REQUIREMENTS),
                 "install_seconds": round(time.monotonic() - started, 1)},
                indent=2,
            )
        )
    return python


def run_blender_script(python: Path, script: Path, *args: str, timeout: float = 600) -> str:
    """Run ``script`` with the Blender environment's interpreter ``python``; return its output.

    Raises
    ------
    BlenderEnvironmentError
        If the script exits non-zero or runs past ``timeout`` (with its output).
    """
    return _run([str(python), str(script), *args], timeout=timeout)
