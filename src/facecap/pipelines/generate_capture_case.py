"""``facecap synth``'s job: a capture case generated with its dense ground truth, written as a folder.

A performance generated on the ICT face (:func:`~facecap.synth.generate_performance`; another actor
with :func:`~facecap.synth.random_identity`) and written as a user would hold it
(:func:`~facecap.synth.write_synthetic_case`: ``scan.obj``, ``take.c3d``, ``map.json``, ``truth.npz``),
or with wrinkle footage filmed by two calibrated cameras (:func:`~facecap.synth.write_footage_case`), or with
footage for the detail layer under calibrated lights (:func:`~facecap.synth.write_detail_case`).
The folder appears whole or not at all; an earlier case there is replaced only with ``overwrite``.
"""

from __future__ import annotations

from pathlib import Path

from ..io.atomic_write import atomic_folder
from ..synth.generate_performance import generate_performance, random_identity
from ..io.ict_sample import load_ict_sample

__all__ = ["generate_capture_case"]

_CASE_FILE = "truth.npz"  # what makes a folder a case, replaced only with overwrite


def generate_capture_case(out_dir: str | Path, *, n_frames: int = 300, seed: int = 0, identity_seed: int = 0,
                          footage: bool = False, levels: int = 2, render_edge_mm: float | None = None,
                          progress: bool = True, overwrite: bool = False, detail: bool = False,
                          appearance: str = "phong") -> None:
    """Generate a capture case with its ground truth (and, with ``footage``, wrinkle footage) into ``out_dir``.

    Parameters
    ----------
    out_dir : str or Path
        The case folder to write.
    n_frames : int, default 300
        Mocap frames.
    seed : int, default 0
        The take, markers and noise (and the wrinkles, skin and sensor of the footage).
    identity_seed : int, default 0
        0: the ICT generic face; K >= 1: a random ICT identity drawn from seed K.
    footage : bool, default False
        Wrinkles on a subdivided scan, filmed by two calibrated cameras
        (:func:`~facecap.synth.write_footage_case`).
    levels : int, default 2
        With ``footage``: subdivisions of the scan.
    render_edge_mm : float or None, default None
        With ``footage``: render from the scan refined around the wrinkles to this edge length, mm;
        None renders the scan itself.
    detail : bool, default False
        With ``footage``: footage for the detail layer instead of the wrinkle layer
        (:func:`~facecap.synth.write_detail_case`: fine lines, studio lights, markers drawn, 25 fps);
        ``render_edge_mm`` is then unused.
    appearance : {'phong', 'independent'}, default 'phong'
        With ``detail``: the skin's reflectance model, lights and line profiles.
    progress : bool, default True
        Progress bars.
    overwrite : bool, default False
        Replace an earlier case in ``out_dir``.
    """
    identity = random_identity(identity_seed) if identity_seed else None
    with atomic_folder(out_dir, marker_file=_CASE_FILE, overwrite=overwrite) as stage:
        if footage and detail:
            from ..synth.write_detail_case import write_detail_case  # the renderer's libraries: only for footage

            write_detail_case(stage, n_frames=n_frames, seed=seed, identity=identity, levels=levels,
                              appearance=appearance, progress=progress)
        elif footage:
            from ..synth.write_footage_case import write_footage_case  # the renderer's libraries: only for footage

            write_footage_case(stage, n_frames=n_frames, seed=seed, identity=identity, levels=levels,
                               render_edge_mm=render_edge_mm, progress=progress)
        else:
            from ..synth.write_synthetic_case import write_synthetic_case

            sample = load_ict_sample()
            case = generate_performance(n_frames=n_frames, seed=seed, identity=identity, sample=sample)
            write_synthetic_case(case, stage, region_labels=sample.region_labels, region_names=list(sample.region_names))
