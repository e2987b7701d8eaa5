"""The benchmark case catalogue: tuned takes and held-out takes (issue 9: a harder generator and a held-out protocol).

Every accuracy benchmark builds its takes from here, so that a number in RESULTS.md
names the case it came from and the cases cannot drift from one script to another.

Protocol
--------
``TUNED_CASES`` are the takes anyone may look at while developing: run the
reconstruction on them, read per-region errors, choose options and tolerances
(``Case.tolerance`` of ``facecap plan-scans`` is tuned on these only). They are the
four default takes of ``bench_scan_accuracy.py`` (seeds 0-3, unchanged) plus four
hard ones: two that mimic studio captures, a speech take and a rapid/asymmetric take; and,
since 2026-12-04, two takes turning about the neck without a head band and a sparse
(45-marker) take with a band swaying 9 degrees, kinds the tuned set lacked when the held-out
takes of those kinds were the ones that missed. Since 2026-12-06 (issue 28): takes whose resting face
is not the scan's (``Case.rest_expression_mm``), maps picked by hand (``map_error_mm``) and a 6-degree
sway without a band, in both sets; two tuned kinds (a resting expression with a hand-picked map, and a
sparse noisy layout) were added after held-out takes of those kinds had been run, each with a fresh
held-out case (``benchmarks/RESULTS.md``, "How the held-out set was used").

``HELD_OUT_CASES`` are for the final report only. Nobody runs a reconstruction on
them while choosing methods or parameters, nor reads their errors to decide
anything; a change is judged on the tuned cases, then the held-out numbers are
measured once and reported as they come, with whatever the method's defaults are
(their ``tolerance`` is a fixed default, never tuned). Their seeds (>= 100),
identities, marker counts (40-120), head motions, curves, noise and gaps do not
appear among the tuned cases. What *is* shared: the ICT face model and its 53
expressions, the generator's code, and for the ``'real'`` curves the one bundled real
take (held-out cases play other, time-stretched and reversed segments of it).

Building a case is cheap (``make_case``: about 1-2 s for 600 frames); generating a
held-out case to check that it builds is fine, reconstructing it is not.

Usage::

    from cases import TUNED_CASES, HELD_OUT_CASES, make_case, case_by_name
    synthetic = make_case(case_by_name("studio_a_real"), n_frames=600)

    python benchmarks/cases.py            # build every case once, print marker statistics
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

from facecap.synth import SyntheticCase, generate_performance, random_rest_expression, write_planned_scans

__all__ = ["ALL_CASES", "HELD_OUT_CASES", "TUNED_CASES", "Case", "case_by_name", "make_case", "scan_case"]

CURVES = ("smooth", "speech", "real", "rapid_asymmetric")


@dataclass(frozen=True)
class Case:
    """One benchmark take.

    Attributes
    ----------
    name : str
        Unique; what a RESULTS.md row quotes.
    held_out : bool
        True: report only, never tune on it (see the module docstring).
    generator : dict
        Keyword arguments of :func:`facecap.synth.generate_performance` other than
        ``curves`` and ``n_frames`` (seed, identity, n_markers, noise_mm,
        gap_fraction, head_rotation_deg, head_translation_mm, head_pivot,
        head_motion, headband_markers, ...).
    curves : {'smooth', 'speech', 'real', 'rapid_asymmetric'}
        The expression-curve generator (``generate_performance(curves=...)``).
    scan_seed : int
        ``first_seed`` of :func:`facecap.synth.write_planned_scans`: the
        scanner simulation of the planned frames.
    tolerance : float
        ``facecap plan-scans --tolerance``, chosen on tuned cases so that the
        plan has 15-30 scans; a fixed default on held-out cases.
    description : str
        What the case stands for.
    rest_expression_mm : float
        0: the take's rest frame shows the scan's expression. Otherwise the
        actor rests with an expression of their own, moving the face by this
        much on average (:func:`facecap.synth.random_rest_expression` drawn
        from the generator's seed), under every frame.
    """

    name: str
    held_out: bool
    generator: dict[str, Any] = field(hash=False)
    curves: str = "smooth"
    scan_seed: int = 0
    tolerance: float = 0.001
    description: str = ""
    rest_expression_mm: float = 0.0

    def __post_init__(self) -> None:
        if self.curves not in CURVES:
            raise ValueError(f"{self.name}: curves must be one of {CURVES}, got {self.curves!r}")
        if {"curves", "n_frames"} & set(self.generator):
            raise ValueError(f"{self.name}: give curves as Case.curves and n_frames to make_case")


def _default(seed: int, tolerance: float) -> Case:
    return Case(f"default_{seed}", False, {"seed": seed, "n_markers": 90}, "smooth", scan_seed=0,
                tolerance=tolerance,
                description="bench_scan_accuracy's take: generic ICT face, 90 markers, head band of 4, "
                            "4 deg sway about the upper neck, 0.2 mm noise, 2 % gaps")


# Re-chosen 2026-12-02 for 15-30 scans after the filter's temporal sigma became cross-validated per
# take (smoother conditioned takes: at the old 0.001, 0.0009, 0.0009 the plans had 8, 12 and 16 scans).
# Near the markers' noise the count jumps (default_0: 25 scans at 0.00088, 12 at 0.00091).
# default_1 re-chosen 2026-12-04 (0.00085 -> 0.0008) when plan-scans took the consensus head pose: 13 scans at the old.
TUNED_CASES: tuple[Case, ...] = (
    _default(0, 0.00088),
    _default(1, 0.0008),
    _default(2, 0.00088),
    _default(3, 0.0011),
    Case("studio_a_real", False,
         {"seed": 10, "identity": (0.72, 1.15, 0.8, -0.68, -0.97, 0.05, 0.6, 0.36), "n_markers": 90,
          "marker_offset_mm": 1.5, "headband_markers": 0, "head_rotation_deg": 0.0, "head_translation_mm": 0.0},
         "real", scan_seed=10,
         description="studio A: real-motion curves on an unseen identity, 90 skin markers 1.5 mm up, no head "
                     "band, head still, the mocap system in its own rigid frame"),
    Case("studio_b_neck_sway", False,
         {"seed": 11, "identity": (1.27, 0.53, 0.45, -0.51, -0.78, 1.04, 0.03, 0.57), "n_markers": 60,
          "noise_mm": 0.3, "headband_markers": 0, "head_rotation_deg": 6.0, "head_pivot": "neck",
          "head_motion": "sway"},
         "smooth", scan_seed=11,
         description="studio B: another identity, 60 markers, 0.3 mm noise, no head band, head swaying up "
                     "to 6 deg about the lower neck"),
    Case("tuned_speech", False,
         {"seed": 12, "identity": (-0.96, -0.31, -0.9, -0.54, 0.63, -1.04, -0.37, 0.11), "n_markers": 90},
         "speech", scan_seed=12,
         description="speech: 4-6 syllables/s jaw and viseme motion, head band of 4, default sway"),
    Case("tuned_rapid_asymmetric", False,
         {"seed": 13, "identity": (-0.47, -0.18, -0.16, 0.29, -0.3, 0.19, 0.04, 0.3), "n_markers": 90,
          "headband_markers": 0},
         "rapid_asymmetric", scan_seed=13,
         description="60-150 ms onsets, L/R intensities and timing differing, no head band"),
    Case("tuned_real_turns", False,
         {"seed": 14, "identity": (0.5, -0.8, 0.9, 0.2, -0.6, 0.4, -0.9, 0.7), "n_markers": 100,
          "noise_mm": 0.25, "gap_fraction": 0.03, "headband_markers": 0, "head_rotation_deg": 8.0,
          "head_translation_mm": 6.0, "head_pivot": "neck", "head_motion": "turns"},
         "real", scan_seed=14,
         description="real-motion curves, 100 markers, no head band, 8 deg turns about the lower neck "
                     "(added 2026-12-04: the tuned set had no head turning about the neck without a band)"),
    Case("tuned_speech_turns", False,
         {"seed": 15, "identity": (-1.1, 0.4, 0.2, -0.9, 0.5, 0.8, 0.3, -0.6), "n_markers": 80,
          "noise_mm": 0.2, "gap_fraction": 0.04, "headband_markers": 0, "head_rotation_deg": 7.0,
          "head_pivot": "neck", "head_motion": "turns"},
         "speech", scan_seed=15,
         description="speech, 80 markers, no head band, 7 deg turns about the lower neck (added 2026-12-04)"),
    Case("tuned_sparse_band_sway", False,
         {"seed": 16, "identity": (0.9, 0.3, -0.7, -0.4, 0.8, -0.2, 0.5, -0.9), "n_markers": 45,
          "noise_mm": 0.3, "gap_fraction": 0.04, "headband_markers": 4, "head_rotation_deg": 9.0,
          "head_translation_mm": 6.0, "head_pivot": "neck", "head_motion": "sway"},
         "smooth", scan_seed=16,
         description="45 markers, head band of 4, 9 deg sway about the lower neck (added 2026-12-04: the tuned "
                     "set had no sparse layout swaying this far)"),
    Case("tuned_rest_real", False,
         {"seed": 17, "identity": (0.3, -0.5, 0.6, 0.9, -0.2, -0.7, 0.4, 0.1), "n_markers": 90,
          "headband_markers": 0, "head_rotation_deg": 0.0, "head_translation_mm": 0.0},
         "real", scan_seed=17, rest_expression_mm=0.42,
         description="real-motion curves, the actor resting with an expression of their own (0.42 mm over the face), "
                     "no head band, head still (added 2026-12-06, issue 28: a resting face that is not the scan's)"),
    Case("tuned_rest_speech_sway", False,
         {"seed": 18, "identity": (-0.6, 0.9, -0.3, 0.2, 0.7, 0.5, -0.8, 0.3), "n_markers": 80, "noise_mm": 0.25,
          "gap_fraction": 0.03, "headband_markers": 0, "head_rotation_deg": 6.0, "head_pivot": "neck",
          "head_motion": "sway"},
         "speech", scan_seed=18, rest_expression_mm=0.5,
         description="speech with a resting expression (0.5 mm), no head band, 6 deg sway about the lower neck "
                     "(added 2026-12-06)"),
    Case("tuned_rest_hand_map", False,
         {"seed": 19, "identity": (0.8, 0.2, -0.9, -0.3, 0.4, 0.6, 0.1, -0.5), "n_markers": 90, "map_error_mm": 1.0,
          "headband_markers": 4},
         "smooth", scan_seed=19, rest_expression_mm=0.4,
         description="a resting expression (0.4 mm) and a map picked by hand, 1 mm off per direction along the skin "
                     "(added 2026-12-06: placement error and a resting expression look alike in one frame)"),
    Case("tuned_rest_hand_map_band", False,
         {"seed": 31, "n_markers": 85, "map_error_mm": 0.8, "headband_markers": 4},
         "smooth", scan_seed=31, rest_expression_mm=0.45,
         description="a resting expression and a hand-picked map 0.8 mm off, head band of 4 (added 2026-12-06 "
                     "after the held-out held_rest_hand_map was kept as an expression and lost: the kind is now tuned)"),
    Case("tuned_rest_hand_map_speech", False,
         {"seed": 33, "n_markers": 70, "map_error_mm": 0.8, "headband_markers": 3},
         "speech", scan_seed=33, rest_expression_mm=0.5,
         description="speech with a resting expression and a hand-picked map 0.8 mm off (added 2026-12-06, as above)"),
    Case("tuned_rest_sparse_speech", False,
         {"seed": 35, "n_markers": 45, "noise_mm": 0.3, "headband_markers": 0, "head_rotation_deg": 4.0,
          "head_pivot": "neck"},
         "speech", scan_seed=35, rest_expression_mm=0.4,
         description="speech, 45 markers, 0.3 mm noise, a resting expression, an exact map, 4 deg sway about the "
                     "neck (added 2026-12-06 after the second held-out run absorbed held_rest_real_still)"),
    Case("tuned_sway6_real", False,
         {"seed": 20, "identity": (-0.2, -0.6, 0.3, -0.8, 0.9, 0.2, -0.4, 0.6), "n_markers": 70, "noise_mm": 0.25,
          "gap_fraction": 0.03, "headband_markers": 0, "head_rotation_deg": 6.0, "head_pivot": "neck",
          "head_motion": "sway"},
         "real", scan_seed=20,
         description="real-motion curves, no head band, 6 deg sway about the lower neck, defaults as a user runs "
                     "them (added 2026-12-06)"),
)

HELD_OUT_CASES: tuple[Case, ...] = (
    Case("held_real_turns", True,
         {"seed": 101, "identity": (0.16, 1.16, -0.46, 0.84, -0.28, -0.67, 0.85, -0.31), "n_markers": 120,
          "noise_mm": 0.25, "gap_fraction": 0.03, "headband_markers": 0, "head_rotation_deg": 8.0,
          "head_translation_mm": 6.0, "head_pivot": "neck", "head_motion": "turns"},
         "real", scan_seed=101,
         description="real-motion curves, 120 markers, no head band, 8 deg turns about the lower neck"),
    Case("held_speech_turns", True,
         {"seed": 102, "identity": (-0.27, -0.97, -1.47, 0.44, -0.82, 0.54, 1.29, -0.08), "n_markers": 70,
          "noise_mm": 0.2, "gap_fraction": 0.04, "headband_markers": 0, "head_rotation_deg": 6.0,
          "head_pivot": "neck", "head_motion": "turns"},
         "speech", scan_seed=102,
         description="speech, 70 markers, no head band, 6 deg turns about the lower neck, 4 % gaps"),
    Case("held_rapid_sway", True,
         {"seed": 103, "identity": (-0.79, 0.28, 0.53, -0.18, 0.01, 0.93, 0.89, 0.5), "n_markers": 40,
          "noise_mm": 0.3, "gap_fraction": 0.05, "headband_markers": 4, "head_rotation_deg": 10.0,
          "head_translation_mm": 8.0, "head_pivot": "neck", "head_motion": "sway"},
         "rapid_asymmetric", scan_seed=103,
         description="rapid/asymmetric, only 40 markers, head band of 4, 10 deg sway about the lower neck, "
                     "5 % gaps"),
    Case("held_real_still", True,
         {"seed": 104, "identity": (-0.61, -0.04, 0.42, -0.15, -0.43, -0.54, -0.44, -0.47), "n_markers": 80,
          "noise_mm": 0.3, "gap_fraction": 0.02, "headband_markers": 0, "head_rotation_deg": 0.0,
          "head_translation_mm": 0.0},
         "real", scan_seed=104,
         description="real-motion curves, 80 markers, no head band, head still (a studio-A twin)"),
    Case("held_smooth_turns", True,
         {"seed": 105, "identity": (-0.32, 0.8, -0.56, 0.62, 0.29, 0.1, -0.58, -0.32), "n_markers": 100,
          "noise_mm": 0.25, "gap_fraction": 0.03, "headband_markers": 0, "head_rotation_deg": 10.0,
          "head_translation_mm": 8.0, "head_pivot": "neck", "head_motion": "turns"},
         "smooth", scan_seed=105,
         description="smooth curves, 100 markers, no head band, 10 deg turns about the lower neck"),
    Case("held_speech_band", True,
         {"seed": 106, "identity": (1.38, 0.07, 0.38, 0.46, 0.74, -0.17, -0.43, -0.04), "n_markers": 50,
          "noise_mm": 0.2, "gap_fraction": 0.05, "headband_markers": 3, "head_rotation_deg": 5.0,
          "head_pivot": "upper_neck", "head_motion": "turns"},
         "speech", scan_seed=106,
         description="speech, 50 markers, head band of 3, 5 deg turns about the upper neck, 5 % gaps"),
    Case("held_rest_real_turns", True,
         {"seed": 107, "identity": (0.62, -1.05, 0.21, 0.37, -0.74, 0.93, -0.12, 0.48), "n_markers": 110,
          "noise_mm": 0.25, "gap_fraction": 0.03, "headband_markers": 0, "head_rotation_deg": 5.0,
          "head_translation_mm": 5.0, "head_pivot": "neck", "head_motion": "turns"},
         "real", scan_seed=107, rest_expression_mm=0.45,
         description="real-motion curves, a resting expression (0.45 mm), 110 markers, no head band, 5 deg turns "
                     "about the lower neck"),
    Case("held_rest_real_still", True,
         {"seed": 108, "identity": (-0.88, 0.35, 0.97, -0.41, 0.12, -0.26, 0.58, -0.93), "n_markers": 60,
          "noise_mm": 0.3, "gap_fraction": 0.02, "headband_markers": 0, "head_rotation_deg": 0.0,
          "head_translation_mm": 0.0},
         "real", scan_seed=108, rest_expression_mm=0.35,
         description="real-motion curves, a resting expression (0.35 mm), 60 markers, 0.3 mm noise, head still"),
    Case("held_sway6_real", True,
         {"seed": 109, "identity": (0.44, 0.71, -0.66, -0.95, 0.28, 0.07, -1.12, 0.39), "n_markers": 75,
          "noise_mm": 0.25, "gap_fraction": 0.04, "headband_markers": 0, "head_rotation_deg": 6.0,
          "head_pivot": "neck", "head_motion": "sway"},
         "real", scan_seed=109,
         description="real-motion curves, no head band, 6 deg sway about the lower neck"),
    Case("held_sway6_speech_rest", True,
         {"seed": 110, "identity": (-0.15, -0.52, -0.84, 0.66, 1.03, -0.61, 0.29, 0.18), "n_markers": 95,
          "noise_mm": 0.2, "gap_fraction": 0.03, "headband_markers": 0, "head_rotation_deg": 6.0,
          "head_pivot": "neck", "head_motion": "sway"},
         "speech", scan_seed=110, rest_expression_mm=0.5,
         description="speech, a resting expression (0.5 mm), no head band, 6 deg sway about the lower neck"),
    Case("held_rest_hand_map", True,
         {"seed": 111, "identity": (1.06, -0.23, 0.51, 0.74, -0.37, -0.98, 0.16, 0.62), "n_markers": 85,
          "map_error_mm": 0.8, "headband_markers": 4},
         "smooth", scan_seed=111, rest_expression_mm=0.45,
         description="a resting expression (0.45 mm) with a map picked by hand 0.8 mm off, head band of 4"),
    Case("held_rest_hand_map_turns", True,
         {"seed": 113, "identity": (0.27, 0.94, -0.38, -1.16, 0.55, 0.31, -0.69, 0.83), "n_markers": 100,
          "noise_mm": 0.25, "map_error_mm": 0.7, "headband_markers": 0, "head_rotation_deg": 5.0,
          "head_pivot": "neck", "head_motion": "turns"},
         "real", scan_seed=113, rest_expression_mm=0.4,
         description="a resting expression (0.4 mm) and a map picked by hand 0.7 mm off, no head band, 5 deg turns "
                     "(added 2026-12-06 with the placement limit, after held_rest_hand_map was seen: this one was not)"),
    Case("held_rest_sparse_turns", True,
         {"seed": 114, "identity": (-1.02, -0.41, 0.66, 0.13, -0.88, 0.47, 0.95, -0.27), "n_markers": 50,
          "noise_mm": 0.3, "gap_fraction": 0.03, "headband_markers": 0, "head_rotation_deg": 5.0,
          "head_pivot": "neck", "head_motion": "turns"},
         "real", scan_seed=114, rest_expression_mm=0.4,
         description="real-motion curves, 50 markers, 0.3 mm noise, a resting expression, an exact map, no head band, "
                     "5 deg turns (added 2026-12-06 with the noise-relative placement limit; not seen before it)"),
    Case("held_hand_map", True,
         {"seed": 112, "identity": (-0.71, 0.88, 0.09, -0.57, -0.46, 0.83, -0.35, -0.22), "n_markers": 65,
          "noise_mm": 0.25, "map_error_mm": 1.2, "headband_markers": 0, "head_rotation_deg": 4.0,
          "head_pivot": "neck", "head_motion": "turns"},
         "real", scan_seed=112,
         description="the scan's own rest expression, a map picked by hand 1.2 mm off, no head band, 4 deg turns"),
)

ALL_CASES: tuple[Case, ...] = TUNED_CASES + HELD_OUT_CASES


def case_by_name(name: str) -> Case:
    """The case called ``name`` (tuned or held out); KeyError lists the names."""
    for case in ALL_CASES:
        if case.name == name:
            return case
    raise KeyError(f"no case {name!r}; expected one of {[c.name for c in ALL_CASES]}")


def add_case_options(parser: argparse.ArgumentParser) -> None:
    """``--cases NAME ...`` and ``--held-out``: which takes a benchmark runs (see :func:`chosen_cases`)."""
    parser.add_argument("--cases", nargs="+", help="case names from cases.py (default: every tuned case)")
    parser.add_argument("--held-out", action="store_true", help="run the held-out set (report only, never tune)")


def chosen_cases(args: argparse.Namespace) -> list[Case]:
    """The cases named by ``--cases``, else the held-out set with ``--held-out``, else the tuned set."""
    if args.cases:
        return [case_by_name(name) for name in args.cases]
    return list(HELD_OUT_CASES if args.held_out else TUNED_CASES)


def make_case(case: Case, *, n_frames: int = 600, **overrides: Any) -> SyntheticCase:
    """Generate the take of ``case`` (``generate_performance(**case.generator, curves=case.curves)``).

    ``overrides`` replace or add generator options (``jaw='rotational'``, say) for a variant of the case.
    """
    kwargs = {**case.generator, **overrides}
    if "identity" in kwargs and kwargs["identity"] is not None:
        kwargs["identity"] = list(kwargs["identity"])
    if case.rest_expression_mm > 0 and "rest_expression" not in overrides:
        kwargs["rest_expression"] = random_rest_expression(kwargs.get("seed", 0), mean_mm=case.rest_expression_mm)
    return generate_performance(n_frames=n_frames, curves=case.curves, **kwargs)


def scan_case(case: Case, synthetic: SyntheticCase, frames: Sequence[int], folder: str | Path,
              **kwargs: Any) -> list[Path]:
    """Scan the planned ``frames`` of ``synthetic`` with the case's scanner seed (:func:`write_planned_scans`)."""
    return write_planned_scans(synthetic, frames, folder, first_seed=case.scan_seed, **kwargs)


def _check_all(n_frames: int = 600) -> None:
    """Build every case once and print its marker statistics (no reconstruction)."""
    import time

    import numpy as np
    from scipy.spatial.transform import Rotation

    names = [c.name for c in ALL_CASES]
    if len(set(names)) != len(names):
        raise SystemExit("duplicate case names")
    print("| case | held out | curves | markers | head band | max marker displacement mm | max head rotation deg "
          "| gaps % | build s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for case in ALL_CASES:
        t = time.perf_counter()
        s = make_case(case, n_frames=n_frames)
        seconds = time.perf_counter() - t
        M = s.n_face_markers
        rel = np.linalg.norm(s.noiseless_markers[:, :M] - s.noiseless_markers[:1, :M], axis=2)
        rot = np.degrees(np.linalg.norm(Rotation.from_matrix(s.head_pose[:, :3, :3]).as_rotvec(), axis=1)).max()
        gaps = 100 * s.markers.gap_mask.mean()
        print(f"| {case.name} | {case.held_out} | {case.curves} | {M} | {len(s.headband_labels)} | {rel.max():.1f} "
              f"| {rot:.1f} | {gaps:.1f} | {seconds:.1f} |", flush=True)


if __name__ == "__main__":
    _check_all()
