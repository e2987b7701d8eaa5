"""Seconds per video frame of the detail footage (write_detail_case) at the default size, both cameras.

    PYTHONPATH=src python benchmarks/bench_detail_footage.py [--frames 4] [--appearance phong] [--out DIR]

Times each video frame from the end of the last (shading, shadows, AO, both cameras' raster, markers,
noise, the first camera's PNG), so the set-up (take, scan refinement, truth, albedo) is reported apart.
"""

from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np

import facecap.cameras as cameras_module
from facecap.io.ict_sample import load_ict_sample
from facecap.synth.wrinkles import every_wrinkle_at_once
from facecap.synth.write_detail_case import DETAIL_VIDEO_EVERY, write_detail_case


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--frames", type=int, default=4, help="video frames to time")
    parser.add_argument("--appearance", default="phong")
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    sample = load_ict_sample()
    n_frames = DETAIL_VIDEO_EVERY * (args.frames - 1) + 1
    curves = every_wrinkle_at_once(n_frames, sample.expression_names, from_frame=0)
    stamps: list[float] = []
    write_sequence = cameras_module.write_image_sequence

    def timed(folder, frames, **kw):  # type: ignore[no-untyped-def]
        def each():  # type: ignore[no-untyped-def]
            stamps.append(time.perf_counter())
            for frame in frames:
                yield frame
                stamps.append(time.perf_counter())
        return write_sequence(folder, each(), **kw)

    cameras_module.write_image_sequence = timed
    out = args.out or tempfile.mkdtemp(prefix="bench_detail_")
    start = time.perf_counter()
    files = write_detail_case(out, n_frames=n_frames, curves=curves, appearance=args.appearance, sample=sample)
    total = time.perf_counter() - start
    per_frame = np.diff(stamps[: args.frames + 1])
    with np.load(files.truth) as truth:
        n = truth["vertices"].shape[1]
    print(f"{args.appearance}: {n} scan vertices, {args.frames} video frames of 1384x1038 x 2 cameras")
    print(f"  per frame s: {np.round(per_frame, 2).tolist()}, median {np.median(per_frame):.2f}")
    print(f"  set-up and files: {total - per_frame.sum():.1f} s; total {total:.1f} s; case in {out}")


if __name__ == "__main__":
    main()
