"""``facecap map`` against the truth: where it places each marker on the scan, on takes it never saw.

The bar measured (issue 28): on generated takes (40-120 markers, any rigid mocap frame, a resting
expression), at least 95 % of the markers placed within 1.5 mm of their true place on the skin, every
other one reported (not placed, or placed and flagged ambiguous or uncertain), without flagging most of
the markers that are within it (false flags: flagged, yet within 1.5 mm); head-band markers found off the
skin and left out. And on the bundled real take (another person's markers on the bundled ICT
face: no true place), ``animate`` driven by the found map has a leave-one-marker-out error no worse than
with the hand-made map.

Run (about 3-5 s a take on 2 cores)::

    python benchmarks/bench_marker_map.py --tuned 50 --no-real        # while tuning: seeds 0-49
    python benchmarks/bench_marker_map.py --held-out 50 --markdown out.md --save out.json   # once, at the end

Protocol
--------
Take ``seed``: :func:`~facecap.synth.generate_performance` with 600 frames at 60 Hz, ``n_markers`` drawn
in 40-120, identity :func:`~facecap.synth.random_identity` (seed), resting expression
:func:`~facecap.synth.random_rest_expression` (seed), a mocap frame drawn uniformly over all rotations
(upside down included) 1 m round the origin; odd seeds carry a head band of 0-5 markers. The scan is
moved into a scanner frame drawn the same way, so that nothing lines up by chance. The job runs as the
command does (:func:`~facecap.pipelines.map_markers`: the take conditioned, the search, the files
written), and the written ``map.json`` is read back with :func:`~facecap.io.read_correspondence` and
compared with ``scan.vertices[case.marker_vertices]``.

Tuned seeds are 0-49 (every choice of the method was made looking at them); held-out seeds start at
2000, with identities, marker counts and expressions drawn from those seeds, never looked at while
tuning; they are run once, at the end, and reported as they come. (Seeds 1000-1049 were the held-out set
of the first version; they have been looked at since and are no longer held out.)

Per take: the face markers placed within 1.5 mm, the misses reported (flagged or not placed) and not
reported, the false flags (ambiguous or uncertain, yet within 1.5 mm), the share of placed markers within
their ``may_be_off_mm``, the head-band markers placed (must be none), the search's score against the next
distinct pose, and the job's wall time (a shared machine: the other processes' load is printed beside it).

The real take: :func:`leave_one_out` of ``bench_accuracy.py`` on the take conditioned by
:func:`~facecap.markers.prepare_take.prepare_markers` (``stabilize=True``) with each map; both maps'
errors are also given relative to the markers' motion in face space, since a map whose layout is
smaller than the markers' shrinks every displacement, and its errors with them.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _load import Window  # noqa: E402
from bench_accuracy import leave_one_out  # noqa: E402

from facecap.markers.prepare_take import prepare_markers  # noqa: E402
from facecap.io.read_correspondence import read_correspondence  # noqa: E402
from facecap.io.read_markers import read_markers  # noqa: E402
from facecap.pipelines import map_markers  # noqa: E402
from facecap.structures import Mesh  # noqa: E402
from facecap.io.ict_sample import bundled_path, load_ict_sample  # noqa: E402
from facecap.synth import generate_performance, random_identity, random_rest_expression  # noqa: E402

WITHIN_MM = 1.5
HELD_OUT_FIRST_SEED = 2000
FRAMES = 600


def _rigid(rng: np.random.Generator, spread_mm: float, rotation_seed: int) -> np.ndarray:
    """A rigid transform: a rotation drawn uniformly (upside down included), a translation within +-spread."""
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rotation_seed).as_matrix()
    T[:3, 3] = rng.uniform(-spread_mm, spread_mm, 3)
    return T


def run_take(seed: int, work: Path) -> dict[str, Any]:
    """One generated take mapped by the job and scored against the truth."""
    rng = np.random.default_rng(seed)
    mocap = _rigid(rng, 1000.0, seed)
    band = int(rng.integers(0, 6)) if seed % 2 else 0
    n_markers = int(rng.integers(40, 121))
    expression = random_rest_expression(seed)
    case = generate_performance(n_frames=FRAMES, n_markers=n_markers, identity=random_identity(seed),
                                rest_expression=expression, headband_markers=band, mocap_frame=mocap, seed=seed)
    scanner = _rigid(rng, 300.0, seed + 100)
    V = case.scan.vertices @ scanner[:3, :3].T + scanner[:3, 3]
    scan = Mesh(V, case.scan.faces, source_path=f"seed{seed}.obj")
    out = work / f"seed{seed}" / "map.json"
    out.parent.mkdir(parents=True)
    with Window() as window, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        report = map_markers(scan, case.markers, out)
    corr = read_correspondence(out, scan)
    M = case.n_face_markers
    labels = list(case.markers.labels)
    truth = V[case.marker_vertices]
    error = np.full(M, np.inf)
    rows = [labels.index(s) for s in corr.labels]
    face = [k for k in rows if k < M]
    error[face] = np.linalg.norm(corr.points(V)[[rows.index(k) for k in face]] - truth[face], axis=1)
    status = [row["status"] for row in report["markers"]]
    flagged = np.array([s in ("ambiguous", "uncertain") for s in status[:M]])
    uncertain = np.array([s == "uncertain" for s in status[:M]])
    estimate = np.array([np.nan if row["may_be_off_mm"] is None else row["may_be_off_mm"]
                         for row in report["markers"][:M]])
    placed = np.isfinite(error)
    within = placed & (error <= WITHIN_MM)
    return {
        "seed": seed, "markers": M, "head_band": band, "expression": {k: round(v, 3) for k, v in expression.items()},
        "within": int(within.sum()), "within_fraction": float(within.mean()),
        "missed_reported": int((~within & (~placed | flagged)).sum()),
        "missed_unreported": int((placed & ~within & ~flagged).sum()),
        "not_placed": int((~placed).sum()), "flagged": int(flagged.sum()),
        "false_flags": int((flagged & within).sum()), "uncertain": int(uncertain.sum()),
        "uncertain_false": int((uncertain & within).sum()),
        "within_estimate": int((placed & (error <= estimate)).sum()), "placed": int(placed.sum()),
        "head_band_placed": int(sum(s in ("placed", "ambiguous", "uncertain") for s in status[M:])),
        "median_mm": float(np.median(error[placed])) if placed.any() else None,
        "max_placed_mm": float(error[placed].max()) if placed.any() else None,
        "score_mm": report["search"]["score_mm"], "second_score_mm": report["search"]["second_score_mm"],
        "sure": report["search"]["sure"], "seconds": window.seconds, "other_cores": window.other_cores,
    }


def summarise(takes: list[dict[str, Any]]) -> dict[str, Any]:
    n = sum(t["markers"] for t in takes)
    worst = min(takes, key=lambda t: t["within_fraction"])
    return {
        "takes": len(takes), "markers": n,
        "within_fraction": sum(t["within"] for t in takes) / n,
        "missed_reported": sum(t["missed_reported"] for t in takes),
        "missed_unreported": sum(t["missed_unreported"] for t in takes),
        "flagged": sum(t["flagged"] for t in takes),
        "false_flags": sum(t["false_flags"] for t in takes),
        "uncertain": sum(t["uncertain"] for t in takes),
        "uncertain_false": sum(t["uncertain_false"] for t in takes),
        "within_estimate": sum(t["within_estimate"] for t in takes) / sum(t["placed"] for t in takes),
        "head_band_markers": sum(t["head_band"] for t in takes),
        "head_band_placed": sum(t["head_band_placed"] for t in takes),
        "takes_below_95": sum(t["within_fraction"] < 0.95 for t in takes),
        "takes_unsure": sum(not t["sure"] for t in takes),
        "worst": worst,
        "seconds_median": float(np.median([t["seconds"] for t in takes])),
        "seconds_max": float(max(t["seconds"] for t in takes)),
    }


def _loo(scan: Mesh, take: Any, path: Path) -> dict[str, Any]:
    corr = read_correspondence(path, scan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        prepared = prepare_markers(take, scan, corr, stabilize=True)
        loo = leave_one_out(scan, prepared)
    error = float(np.mean([m["shell_mean_mm"] for m in loo["per_marker"]]))
    motion = float(np.mean([m["motion_rms_mm"] for m in loo["per_marker"]]))
    return {"markers": len(prepared.labels), "shell": loo["stats"]["shell"], "warp": loo["stats"]["warp"],
            "per_marker_mean_mm": error, "motion_rms_mean_mm": motion, "error_per_motion": error / motion,
            "labels": list(prepared.labels)}


def _layout_ratio(A: np.ndarray, B: np.ndarray) -> float:
    """Median ratio of the pairwise distances of two point sets, row for row (rows with NaN left out)."""
    ok = np.isfinite(A).all(axis=1) & np.isfinite(B).all(axis=1)
    i, j = np.triu_indices(int(ok.sum()), k=1)
    a, b = A[ok], B[ok]
    return float(np.median(np.linalg.norm(a[i] - a[j], axis=1) / np.linalg.norm(b[i] - b[j], axis=1)))


def run_real(work: Path) -> dict[str, Any]:
    """The bundled real take: the found map's leave-one-out error beside the hand-made map's."""
    scan = load_ict_sample().mesh
    take = read_markers(bundled_path("eyebrows.c3d"))
    found_path = work / "real" / "map.json"
    found_path.parent.mkdir(parents=True)
    with Window() as window, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        report = map_markers(scan, take, found_path)
    hand_path = bundled_path("ict_generic_map.json")
    hand = _loo(scan, take, hand_path)
    found = _loo(scan, take, found_path)
    hand_doc = json.loads(Path(hand_path).read_text())
    same = work / "real" / "hand_same_markers.json"
    same.write_text(json.dumps({s: hand_doc[s] for s in found["labels"]}))
    hand_same = _loo(scan, take, same)
    corr = read_correspondence(hand_path, scan)
    columns = [take.labels.index(s) for s in corr.labels]
    return {
        "summary": report["summary"], "seconds": window.seconds,
        "hand": hand, "found": found, "hand_on_found_markers": hand_same,
        "hand_layout_size_ratio": _layout_ratio(corr.points(scan.vertices), take.positions[0, columns]),
    }


def markdown(results: dict[str, Any]) -> str:
    lines = [f"## `facecap map` ({results['date']}, {results['machine']})", ""]
    for key, title in (("tuned", "Tuned seeds (0-49)"), ("held_out", f"Held-out seeds (>= {HELD_OUT_FIRST_SEED})")):
        if key not in results:
            continue
        s = results[key]["summary"]
        w = s["worst"]
        lines += [
            f"**{title}**: {s['takes']} takes, {s['markers']} face markers; placed within {WITHIN_MM} mm of the "
            f"true place: **{100 * s['within_fraction']:.2f} %**; the other markers: {s['missed_reported']} reported "
            f"(not placed, or flagged), {s['missed_unreported']} not reported; {s['flagged']} markers flagged in all, "
            f"{s['false_flags']} of them within {WITHIN_MM} mm (false flags; uncertain: {s['uncertain']} flagged, "
            f"{s['uncertain_false']} false); placed markers within their `may_be_off_mm`: "
            f"{100 * s['within_estimate']:.1f} %; "
            f"head-band markers placed: {s['head_band_placed']} of {s['head_band_markers']}; takes under 95 %: "
            f"{s['takes_below_95']}; search unsure: {s['takes_unsure']}. Worst take: seed {w['seed']} ({w['markers']} "
            f"markers, resting expression {w['expression']}): {100 * w['within_fraction']:.1f} % within, "
            f"{w['missed_reported']} reported, {w['missed_unreported']} not. Time per take (the whole job, "
            f"conditioning and picture included): median {s['seconds_median']:.1f} s, at most "
            f"{s['seconds_max']:.1f} s.",
            "",
        ]
    if "real" in results:
        r = results["real"]
        row = "| {} | {} | {:.3f} | {:.3f} | {:.3f} | {:.3f} |"
        lines += ["**Bundled real take** (AnimFace `eyebrows.c3d` on the ICT face), leave-one-marker-out:", "",
                  "| map | markers | shell mean (mm) | shell p95 (mm) | warp mean (mm) | error / motion |",
                  "|---|---|---|---|---|---|"]
        for name, key in (("hand-made", "hand"), ("hand-made, the found map's markers", "hand_on_found_markers"),
                          ("found by `facecap map`", "found")):
            m = r[key]
            lines.append(row.format(name, m["markers"], m["shell"]["mean_mm"], m["shell"]["p95_mm"],
                                    m["warp"]["mean_mm"], m["error_per_motion"]))
        lines += ["", f"The hand-made map's layout is {r['hand_layout_size_ratio']:.3f} times the size of the "
                      "markers' own (median ratio of pairwise distances), so its warp shrinks the motion, and the "
                      "errors, by about as much.", ""]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--tuned", type=int, default=0, help="tuned takes to run: seeds 0..N-1 [0]")
    ap.add_argument("--held-out", type=int, default=0, help=f"held-out takes: seeds {HELD_OUT_FIRST_SEED}.. [0]")
    ap.add_argument("--no-real", action="store_true", help="skip the bundled real take")
    ap.add_argument("--markdown", type=Path, default=None)
    ap.add_argument("--save", type=Path, default=None)
    args = ap.parse_args()
    results: dict[str, Any] = {"date": time.strftime("%Y-%m-%d"),
                               "machine": f"{platform.node()} {platform.processor()}"}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for key, seeds in (("tuned", range(args.tuned)),
                           ("held_out", range(HELD_OUT_FIRST_SEED, HELD_OUT_FIRST_SEED + args.held_out))):
            if not len(seeds):
                continue
            takes = []
            for seed in seeds:
                t = run_take(seed, work)
                takes.append(t)
                print(f"{key} seed {seed}: {t['markers']} markers, band {t['head_band']}, within "
                      f"{100 * t['within_fraction']:.1f} %, missed reported {t['missed_reported']} / not "
                      f"{t['missed_unreported']}, flagged {t['flagged']} (false {t['false_flags']}), band placed {t['head_band_placed']}, score {t['score_mm']:.2f} / "
                      f"{t['second_score_mm']}, {t['seconds']:.1f} s (others {t['other_cores']:.1f} cores)", flush=True)
            results[key] = {"takes": takes, "summary": summarise(takes)}
        if not args.no_real:
            results["real"] = run_real(work)
    text = markdown(results)
    print(text)
    if args.markdown:
        args.markdown.write_text(text + "\n")
    if args.save:
        args.save.write_text(json.dumps(results, indent=1, default=float) + "\n")


if __name__ == "__main__":
    main()
