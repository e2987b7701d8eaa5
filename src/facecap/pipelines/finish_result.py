"""The end every job's result folder shares: the exports made from the finished frames, the pages, the rename.

A job streams its frames (or its rig) through a :class:`facecap.io.PerformanceWriter`;
:func:`finish_result` then, in the writer's staging folder,

1. writes the metadata (:meth:`~facecap.io.PerformanceWriter.write_metadata`), after which the
   folder reads as a result;
2. makes the exports that read the finished frames (glTF, point caches, Alembic, USD blend
   shapes: :func:`facecap.pipelines.export_result`, which records them in ``performance.json``);
3. writes ``review.html`` when a glTF was written (:func:`facecap.report.write_review_page`)
   and ``report.html`` (:func:`facecap.report.write_run_report`);
4. has the writer list every file in ``performance.json`` and move the folder into place
   (:meth:`~facecap.io.PerformanceWriter.finish`).

:func:`import_writers` imports what steps 2 and 3 will need ahead of time.
"""

from __future__ import annotations

import importlib
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any, Iterable

from ..io.write_performance import PerformanceWriter

__all__ = ["finish_result", "import_writers"]

_WRITER_MODULES = {
    "usd": ("facecap.io.write_usd", "facecap.io.write_usd_blendshapes", "pxr.Usd", "pxr.UsdGeom", "pxr.UsdSkel"),
    "gltf": ("facecap.pipelines.write_gltf_review",),
}
"""Modules each export's writers import when they start, beyond what every run needs."""


def finish_result(writer: PerformanceWriter, metadata: dict[str, Any]) -> Path:
    """Write the metadata, the exports made from the frames and the pages, then move the folder into place.

    Parameters
    ----------
    writer : PerformanceWriter
        Every frame (or the rig) written; its ``exports`` and ``export_options``
        say what to export.
    metadata : dict
        As for :meth:`facecap.io.PerformanceWriter.write_metadata`.

    Returns
    -------
    Path
        The finished output folder.

    Raises
    ------
    InputError
        As the writer and the exports raise it; the staging folder is then
        discarded when the writer's ``with`` block exits.
    """
    from ..report.review_page import write_review_page
    from ..report.write_run_report import write_run_report

    staging = writer.write_metadata(metadata)
    later = writer.later_exports
    plots: dict[bytes, bytes] = {}
    if later:
        from .export_result import export_result

        options = dict(writer.export_options)
        # The page's plots show the run's own figures, not the exports': drawn beside the exports (numpy and
        # the disk while matplotlib draws; 0.3-0.5 s of a 10,000-frame take), kept by the report, and the page
        # written again after them with the exports' results. Only a draft is lost if that first page fails.
        with ThreadPoolExecutor(1) as beside_exports:  # waits for the draft; a draft that failed is not looked at
            beside_exports.submit(write_run_report, staging, drawn_plots=plots)
            export_result(staging, later, progress=options.pop("progress", False), skip_streamed=True, pages=False,
                          **options)
    glb = staging / "performance.glb"
    if glb.is_file():
        write_review_page(staging / "review.html", glb, title=f"facecap: {writer.out_dir.name}",
                          rate=writer.rate, n_frames=writer.n_frames)
    write_run_report(staging, drawn_plots=plots)
    return writer.finish()


def import_writers(exports: Iterable[str]) -> None:
    """Import the modules :func:`finish_result` will need for ``exports`` and the run's report page.

    For a caller that wants the cost (the USD libraries 0.12 s, matplotlib for
    the report's plots 0.25 s) before its long work rather than at the end, or
    an import error at once. Call it where no other thread loads a library
    meanwhile: a compiled module loading on one thread while another thread
    loads one can deadlock (seen: usd-core's initialisers against MKL's first
    load inside PARDISO; :func:`facecap.mesh.load_backend` loads MKL's first).
    """
    names = ["facecap.pipelines.export_result",  # its exports
             "facecap.report.write_run_report", "facecap.report.html_report"]  # report.html: every run
    for fmt in exports:
        names.extend(_WRITER_MODULES.get(fmt, ()))
    for name in names:
        importlib.import_module(name)
