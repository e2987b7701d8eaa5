"""One installer at a time for the tools the tests install on first use.

The suite runs on several worker processes (pytest-xdist, ``addopts`` in ``pyproject.toml``), and two
test files on two workers may ask for the same missing tool at once: two ``npm ci`` in one folder, or two
``apt-get install`` behind dpkg's lock, would fail each other. Each installer holds an exclusive lock
file for its tool while it checks and installs; the second waits, checks again and finds it installed.
"""

from __future__ import annotations

import fcntl
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def cache_root() -> Path:
    """The folder holding the test tools' cached environments and their lock files.

    ``$FACECAP_TEST_CACHE``, else ``$XDG_CACHE_HOME/facecap-tests``, else ``~/.cache/facecap-tests``.
    """
    if os.environ.get("FACECAP_TEST_CACHE"):
        return Path(os.environ["FACECAP_TEST_CACHE"]).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "facecap-tests"


@contextmanager
def install_lock(tool: str) -> Iterator[None]:
    """Hold ``<cache_root>/<tool>.lock`` exclusively (across processes) for the body of the ``with``."""
    root = cache_root()
    root.mkdir(parents=True, exist_ok=True)
    with open(root / f"{tool}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        yield
