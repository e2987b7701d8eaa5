"""Derive ``facecap.synth.rotational_jaw.ICT_JAW_SCREW`` from the full ICT model (needs ../shared/data).

The lower teeth (ICT vertices 17039-21450 that ``jawOpen`` moves more than 30 % of the most) are
rigid under ``jawOpen``; their screw motion, in the bundled sample's frame (the model's cm times 10),
is the jaw's. Prints the constant and the fit's residual.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from facecap.synth.rotational_jaw import fit_jaw_screw

TEETH = np.arange(17039, 21451)
MM_PER_CM = 10.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--source", type=Path, default=Path("/work/shared/data"))
    args = ap.parse_args()
    data = np.load(args.source / "ict_face" / "expressions.npz", allow_pickle=True)
    names = [str(n) for n in data["names"]]
    neutral = data["neutral"].astype(np.float64) * MM_PER_CM
    opened = data["shapes"][names.index("jawOpen")].astype(np.float64) * MM_PER_CM
    moved = np.linalg.norm(opened[TEETH] - neutral[TEETH], axis=1)
    lower = TEETH[moved > 0.3 * moved.max()]
    screw = fit_jaw_screw(neutral[lower], opened[lower])
    residual = np.linalg.norm(screw.apply(neutral[lower], 1.0) - opened[lower], axis=1)
    print(f"axis {screw.axis.round(6).tolist()}, angle {np.degrees(screw.angle_rad):.6f} deg, "
          f"centre {screw.centre.round(6).tolist()} mm, slide {screw.slide_mm:.6f} mm")
    print(f"{lower.size} lower-teeth vertices, residual mean {residual.mean():.3f} mm, max {residual.max():.3f} mm")


if __name__ == "__main__":
    main()
