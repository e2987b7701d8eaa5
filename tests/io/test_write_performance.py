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
