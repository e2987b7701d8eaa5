"""Tests for facecap.report.html_report: a run's report as a capture TD reads it.

The report of a small real run (``facecap animate`` through the CLI, as a user runs it, on the
analytic capture case with head motion and a head band that is not in the map) is opened in a
real headless Chromium; its visible text must give the summary first with ``report.json``'s
numbers in their units, the quality figures with what they mean, every warning of
``report.json`` with its explanation, no raw key names, file sizes with units, and a screenshot
that is not blank. Fast tests build pages from hand-made reports: the figures of each command,
the head-motion and rest-pose sections, and missing or malformed keys (a folder from an older
facecap) that leave their part out instead of failing.
"""

from __future__ import annotations

import json
import re
import warnings
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.image import imread, imsave

from facecap.cli import main
from facecap.report import html_report, write_html_report

from analytic_case import CaptureCase
from browser import launch_browser, open_page

SIZE_UNITS = {"B": 1, "kB": 1e3, "MB": 1e6, "GB": 1e9}


@pytest.fixture(scope="module")
def browser():
    with launch_browser() as b:
        yield b


@pytest.fixture(scope="module")
def real_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any], dict[str, Any]]:
    """``facecap animate --stabilize auto`` on the analytic case: the folder, report.json and performance.json."""
    root = tmp_path_factory.mktemp("run")
    case = CaptureCase(root, head_motion=True)
    out = root / "result"
    assert main(["--quiet", "animate", "--scan", str(case.scan_path), "--markers", str(case.markers_path),
                 "--map", str(case.map_path), "--out", str(out), "--stabilize", "auto"]) == 0
    return out, json.loads((out / "report.json").read_text()), json.loads((out / "performance.json").read_text())


def _numbers(text: str, unit: str) -> list[float]:
    """Every number written with ``unit`` in ``text`` (thousands separators and exponents allowed)."""
    return [float(m.replace(",", "")) for m in re.findall(rf"(-?[\d,]*\.?\d+(?:e[-+]?\d+)?) ?{re.escape(unit)}\b",
                                                            text)]


def _keys(value: Any, skip: frozenset[str] = frozenset({"warp_leave_one_out_mm", "per_marker_mm", "files",
                                                         "flags"})) -> set[str]:
    """Every key of a JSON document, less those of mappings keyed by marker label, file name or frame."""
    found: set[str] = set()
    if isinstance(value, dict):
        for k, v in value.items():
            found.add(k)
            if k not in skip:
                found |= _keys(v, skip)
    elif isinstance(value, list):
        for v in value:
            found |= _keys(v, skip)
    return found


def test_report_of_a_real_run_in_chromium(browser: object, real_run: tuple, tmp_path: Path) -> None:
    out, report, performance = real_run
    with open_page(browser, (out / "report.html").as_uri(), width=1000, height=900) as (page, watch):
        page.wait_for_load_state("load")
        text = page.inner_text("body")

        # what comes first: the summary, then the figures, the warnings, the details
        headings = page.eval_on_selector_all("h2", "hs => hs.map(h => h.innerText)")
        assert headings[0] == "Summary"
        assert [h for h in headings if h in ("Summary", "Quality", "Warnings", "Details")] == \
            ["Summary", "Quality", "Warnings", "Details"]
        summary = dict(page.eval_on_selector_all("table.summary tr",
                                                 "rows => rows.map(r => [r.cells[0].innerText, r.cells[1].innerText])"))
        assert summary["Command"].startswith("facecap animate")
        assert summary["Frames"].startswith(f"{report['n_frames']} frames × {report['n_vertices']} vertices")
        assert summary["Markers"].startswith(f"{report['n_markers']} on the face")
        assert summary["Rate"].startswith(f"{performance['rate']:g} Hz")
        assert _numbers(summary["Rate"], "s") == pytest.approx([report["n_frames"] / performance["rate"]], rel=5e-3)
        assert summary["Units"].startswith(performance["units"])
        assert summary["Scan"].startswith("scan.obj") and summary["Take"].startswith("take.c3d")
        assert _numbers(summary["Time taken"], "s")[0] == pytest.approx(report["timings"]["total_s"], rel=5e-3)
        assert summary["Head motion"].startswith("found and removed")
        assert all(label in summary["Head motion"] for label in performance["parameters"]["stable_markers"])
        assert summary["Warnings"].startswith(str(len(report["warnings"])))

        # the quality figures: report.json's numbers in mm, each with what it means
        blocks = {b[0]: b[1:] for b in page.eval_on_selector_all(
            "div.block", "bs => bs.map(b => [b.querySelector('h3').innerText.replace(/look at this$/, ''), "
                         "b.querySelector('.value').innerText, b.querySelector('.about').innerText])")}
        first = performance["first_frame"]
        per_frame = np.array(report["marker_residual_mm"]["per_frame_max"])
        value = blocks["Marker residual"][0]
        assert _numbers(value, "mm") == pytest.approx([report["marker_residual_mm"]["max"]], rel=0.03)
        assert f"(frame {first + int(np.argmax(per_frame))})" in value
        loo = report["warp_leave_one_out_mm"]
        worst = max(loo, key=loo.get)
        value = blocks["Leave-one-out warp residual"][0]
        assert _numbers(value, "mm") == pytest.approx([np.median(list(loo.values())), loo[worst]], rel=5e-3)
        assert f"({worst})" in value
        stabilisation = np.array(report["stabilization_residual_mm"])
        assert _numbers(blocks["Stabilisation residual"][0], "mm") == pytest.approx(
            [np.median(stabilisation), stabilisation.max()], rel=5e-3)
        change = np.array(report["conditioning_mm"]["per_frame_rms_change"])
        assert _numbers(blocks["Change by conditioning"][0], "mm") == pytest.approx(
            [np.median(change), change.max()], rel=5e-3)
        assert blocks["Noise filter width"][0].startswith(f"{report['temporal_sigma']['sigma_s']:g} s")
        assert all(len(about) > 40 for _, about in blocks.values())
        plots = page.eval_on_selector_all("img", "imgs => imgs.filter(i => i.alt.startsWith('plot:'))"
                                                 ".map(i => i.naturalWidth)")
        assert len(plots) >= 3 and all(w == 900 for w in plots)

        # every warning of report.json, with what it means and what to do (here: head-band markers)
        shown = page.eval_on_selector_all("div.warning", "ws => ws.map(w => w.innerText)")
        assert len(shown) == len(report["warnings"]) >= 1
        for message, block in zip(report["warnings"], shown):
            assert message in block
            assert "What it means:" in block and "What to do:" in block
        # the take's markers outside the map (a head band), and its markers on the skin where the offset says
        # 1.5 mm: both explained
        assert any("head-band" in block for block in shown)
        assert any("--marker-offset" in block for block in shown)

        # no key of report.json or performance.json is shown as a label
        prose = text
        for message in report["warnings"] + report["notes"]:
            prose = prose.replace(message, "")
        raw = [k for k in _keys(report) | _keys(performance)
               if "_" in k and re.search(rf"(?<![\w./-]){re.escape(k)}(?![\w.])", prose)]
        assert raw == []

        # the details: timings once, every file with its size in B, kB, MB or GB
        assert page.eval_on_selector_all("h3", "hs => hs.map(h => h.innerText)").count("Timings") == 1
        assert text.count("Condition and warp") == 1  # each timing once
        files = page.eval_on_selector_all("table.files tbody tr", "rows => rows.map(r => [r.cells[0].innerText, "
                                                                  "r.cells[1].innerText])")
        listed = {name: size for name, size in files if name != "all files"}
        on_disk = {p.relative_to(out).as_posix(): p.stat().st_size for p in out.rglob("*")
                   if p.is_file() and p.name not in ("report.html", "performance.json")}
        assert set(listed) == set(on_disk)
        for name, size in listed.items():
            number, unit = re.fullmatch(r"([\d.,]+) (B|kB|MB|GB)", size).groups()
            assert float(number.replace(",", "")) * SIZE_UNITS[unit] == pytest.approx(on_disk[name], rel=5e-3)

        # the per-marker table is collapsed: opened, it holds every marker's leave-one-out residual
        best = min(loo, key=loo.get)
        assert page.eval_on_selector("details", "d => d.open") is False
        assert f"{best}\t" not in text
        page.click("details > summary")
        rows = dict(page.eval_on_selector_all("table.markers tbody tr",
                                              "rows => rows.map(r => [r.cells[0].innerText, r.cells[1].innerText])"))
        assert set(loo) <= set(rows)
        assert float(rows[best]) == pytest.approx(loo[best], rel=0.03, abs=1e-4)
        page.click("details > summary")
        page.emulate_media(media="print")  # printed, the table is open
        assert f"{best}\t" in page.inner_text("body")
        page.emulate_media(media="screen")

        shot_path = tmp_path / "report.png"
        page.screenshot(path=str(shot_path), full_page=True)
        assert watch.problems() == []
    shot = imread(shot_path)
    assert shot.shape[0] > 1500 and shot.shape[1] == 1000
    assert shot[..., :3].std() > 0.05  # not blank


def test_plots_are_labelled_in_units_against_the_frame(real_run: tuple, tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    out, report, performance = real_run
    calls = []
    real_plot = html_report.plot_series

    def recording(times: Any, series: Any, path: Any, **options: Any) -> None:
        calls.append((np.asarray(times), options))
        real_plot(times, series, path, **options)

    monkeypatch.setattr(html_report, "plot_series", recording)
    write_html_report(tmp_path / "report.html", out)
    assert len(calls) >= 3
    frames = performance["first_frame"] + np.arange(report["n_frames"])
    for times, options in calls:
        np.testing.assert_array_equal(times, frames)
        assert options["xlabel"] == "frame"
        assert re.fullmatch(r"[A-Za-z][A-Za-z -]* \(mm\)", options["ylabel"]), options["ylabel"]


# ------------------------------------------------------------------------------------------- hand-made reports

class _Text(HTMLParser):
    """The text of a page as a reader sees it: no style, script or markup; cells and blocks on their own."""

    def __init__(self) -> None:
        super().__init__()
        self.parts: list[str] = []
        self._hidden = 0

    def handle_starttag(self, tag: str, attrs: Any) -> None:
        self._hidden += tag in ("style", "script", "title")
        if tag in ("p", "tr", "h1", "h2", "h3", "li", "div", "figcaption", "summary"):
            self.parts.append("\n")
        elif tag in ("td", "th") and self.parts and self.parts[-1] != "\n":
            self.parts.append("\t")  # between cells: a row's first cell starts its line

    def handle_endtag(self, tag: str) -> None:
        self._hidden -= tag in ("style", "script", "title")

    def handle_data(self, data: str) -> None:
        if not self._hidden:
            self.parts.append(data)


def _text(page: Path) -> str:
    parser = _Text()
    parser.feed(page.read_text())
    return "".join(parser.parts)


@pytest.fixture
def fast_plots(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """plot_series replaced by a 2 x 2 PNG (these tests are about the page, the plots have their own); ylabels."""
    labels: list[str] = []

    def tiny(times: Any, series: Any, path: Any, **options: Any) -> None:
        labels.append(options["ylabel"])
        imsave(path, np.zeros((2, 2, 3)), format="png")

    monkeypatch.setattr(html_report, "plot_series", tiny)
    return labels


T = 6
LABELS = ["brow_L", "brow_R", "nose", "chin", "lip_up", "lip_down"]
PERFORMANCE = {
    "format": "facecap-performance", "version": 1, "rate": 120.0, "units": "cm", "n_frames": T, "n_vertices": 5000,
    "exports": ["gltf"], "source_files": {"scan": "/data/actor/scan.obj", "markers": "/data/actor/take_012.c3d"},
    "source_units": {"scan": "cm", "markers": "mm"}, "method": "bickel2007-large-scale", "rest_frame": 2,
    "stabilized": True, "first_frame": 100, "map": "map.json",
    "parameters": {"ks": 1.0, "kb_mm2": 100.0, "marker_offset_mm": 3.0, "stable_markers": ["HB0", "HB1", "HB2"]},
    "markers": LABELS, "timings": {"total_s": 75.0},
}
REPORT = {
    "timings": {"condition_markers_s": 0.5, "deform_and_write_s": 70.0, "frames_per_second": 0.0857, "total_s": 75.0},
    "n_frames": T, "n_vertices": 5000, "n_markers": len(LABELS),
    "mesh_check": {"n_vertices": 5000, "n_faces": 9800, "n_degenerate_faces": 2, "n_pieces": 1,
                   "bounding_box_mm": [[0, 0, 0], [150, 220, 120]], "mean_edge_length_mm": 2.5, "problems": []},
    "warp_leave_one_out_mm": {"brow_L": 0.4, "brow_R": 0.5, "nose": 0.3, "chin": 7.5, "lip_up": 0.6, "lip_down": 0.45},
    "warp_outliers": ["chin"],
    "marker_residual_mm": {"per_frame_max": [0.01, 0.02, 0.03, 0.02, 0.01, 0.0], "max": 0.03},
    "marker_offset_correction_mm": {"per_frame_max": [0.1] * T, "mean": 0.05, "max": 0.1},
    "conditioning_mm": {"per_frame_rms_change": [0.2, 0.3, 0.25, 0.2, 0.2, 0.1]},
    "temporal_sigma": {"sigma_s": 0.02, "chosen_by": "leave-self-out cross-validation",
                       "candidates_s": [0.005, 0.02, 0.1], "scores_mm2": [0.2, 0.1, 0.15], "scored_frames": T},
    "filled_samples": 9, "stabilization_residual_mm": [0.2] * T,
    "head_motion": {"mode": "auto", "stabilized": True, "pose_from": "head band",
                    "stable_markers": ["HB0", "HB1", "HB2"],
                    "max_rotation_deg": 6.25, "max_translation_mm": 12.5,
                    "warnings": ["the rigid set for the head motion holds lip_up, a marker on the lips"]},
    "rest_pose": {"mode": "expression", "chosen_by": "auto", "reason": "the mismatch is 8 times the noise",
                  "noise_mm": 0.05, "rest_noise_mm": 0.02, "mismatch_rms_mm": 0.42, "expression_rms_mm": 0.38,
                  "placement_rms_mm": 0.15,
                  "per_marker_mm": {"brow_L": 0.2, "brow_R": 0.25, "nose": 0.05, "chin": 0.9, "lip_up": 1.06,
                                    "lip_down": 0.7}},
    "notes": ["9 occluded marker samples filled"],
    "warnings": ["4 take marker(s) are not in the marker map, so they do not drive the face (they may still give the head's motion): ['HB0', 'HB1', 'HB2', 'HB3']"],
}


def _folder(tmp_path: Path, performance: dict[str, Any] | None = PERFORMANCE) -> Path:
    folder = tmp_path / "result"
    folder.mkdir()
    if performance is not None:
        (folder / "performance.json").write_text(json.dumps(performance))
    (folder / "vertices.npy").write_bytes(b"\0" * 2_345_678)
    return folder


def test_the_summary_states_the_run_in_units(tmp_path: Path, fast_plots: list[str]) -> None:
    folder = _folder(tmp_path)
    text = _text(write_html_report(tmp_path / "r.html", folder, report=REPORT))
    summary = text[text.index("\nSummary\n"):text.index("\nQuality\n")]
    assert "\tscan.obj (cm)" in summary and "\ttake_012.c3d (mm), rest frame 2" in summary
    assert "\t6 frames × 5,000 vertices (frames 100–105 of the take)" in summary
    assert "\t120 Hz, 0.05 s of the take" in summary
    assert "\tcm (the unit of the written files)" in summary
    assert "\t1 min 15 s" in summary
    # head motion and rest pose in a line each, from the sections being added to report.json
    assert "found and removed (from head band: HB0, HB1, HB2): up to 6.25° and 12.5 mm" in summary
    assert ("rest frame 2 holds an expression of its own, kept as motion (chosen automatically: the mismatch is "
            "8 times the noise)") in summary
    assert "\t2, explained below" in summary  # report.json's warning and head_motion's
    order = [text.index(f"\n{heading}\n") for heading in ("Summary", "Quality", "Warnings", "Details")]
    assert order == sorted(order)



def test_a_page_written_again_from_the_same_figures_draws_no_plot_twice(tmp_path: Path, fast_plots: list[str]) -> None:
    folder = _folder(tmp_path)
    drawn: dict[bytes, bytes] = {}
    first = write_html_report(tmp_path / "a.html", folder, report=REPORT, drawn_plots=drawn).read_text()
    n = len(fast_plots)
    assert n >= 2 and len(drawn) == n
    second = write_html_report(tmp_path / "b.html", folder, report=REPORT, drawn_plots=drawn).read_text()
    assert len(fast_plots) == n  # nothing drawn again
    strip = lambda page: re.sub(r"written \S+ \S+ UTC", "", page)  # noqa: E731
    assert strip(first) == strip(second)
    changed = json.loads(json.dumps(REPORT))
    changed["marker_residual_mm"]["per_frame_max"][0] += 1.0  # one figure changed: that plot alone is drawn
    write_html_report(tmp_path / "c.html", folder, report=changed, drawn_plots=drawn)
    assert len(fast_plots) == n + 1

def test_quality_figures_and_warnings_are_explained(tmp_path: Path, fast_plots: list[str]) -> None:
    text = _text(write_html_report(tmp_path / "r.html", _folder(tmp_path), report=REPORT))
    quality = text[text.index("\nQuality\n"):text.index("\nWarnings\n")]
    assert "median 0.475 mm, largest 7.5 mm (chin); flagged: chin" in quality
    # the noise named is the one the reason's "times the noise" means: the rest markers' in 3-D (sqrt(3) x 0.02)
    assert "mismatch 0.42 mm RMS after the rigid fit, against the rest frame's noise of 0.0346 mm (3-D) and a " \
           "single frame's 0.05 mm a coordinate; of which shared by neighbours 0.38 mm RMS and each marker's own " \
           "0.15 mm RMS" in quality
    assert "Farthest: lip_up 1.06 mm, chin 0.9 mm" in quality
    assert "largest 0.03 mm (frame 102)" in quality  # frame numbers are the take's
    assert "9 of 36 marker samples (25%)" in quality
    assert "0.02 s (2.4 frames at 120 Hz)" in quality and "inside the range tried" in quality
    assert quality.count("look at this") == 4  # a flagged marker, the rest pose, the head-motion warning, gaps
    warnings_part = text[text.index("\nWarnings\n"):text.index("\nNotes\n")]
    assert "lip_up, a marker on the lips" in warnings_part and "jaw or lips" in warnings_part
    assert "no place on the scan" in warnings_part
    assert warnings_part.count("What it means:") == 2 == warnings_part.count("What to do:")
    assert all(re.search(r"\((mm|mN)\)$", label) for label in fast_plots)


def test_details_give_timings_once_sizes_with_units_and_readable_names(tmp_path: Path,
                                                                      fast_plots: list[str]) -> None:
    report = {**REPORT, "a_new_figure_mm": 1.5, "another_one": {"count_of_things": 3}}
    text = _text(write_html_report(tmp_path / "r.html", _folder(tmp_path), report=report))
    details = text[text.index("\nDetails\n"):]
    assert details.count("\nTimings\n") == 1 and "\nDeform and write\t1 min 10 s" in details
    assert "\nvertices.npy\t2.35 MB" in details and "\nperformance.json\t" not in details
    assert "\nStretching stiffness (ks)\t1" in details and "\nBending stiffness (kb)\t100 mm²" in details
    assert "\nchin\t7.5\t0.9\tflagged" in details  # the per-marker table: both columns and the flag
    assert "\nDefects\t2 degenerate triangles" in details and "\nSize\t150 × 220 × 120 mm" in details
    assert "\nA new figure\t1.5 mm" in details and "\nAnother one: count of things\t3" in details
    raw = [k for k in _keys(report) | _keys(PERFORMANCE) if "_" in k and re.search(
        rf"(?<![\w./-]){re.escape(k)}(?![\w.])", text.replace(REPORT["warnings"][0], ""))]
    assert raw == []


@pytest.mark.parametrize("key", [k for k in REPORT] + [f"head_motion.{k}" for k in REPORT["head_motion"]]
                         + [f"rest_pose.{k}" for k in REPORT["rest_pose"]]
                         + [f"temporal_sigma.{k}" for k in REPORT["temporal_sigma"]])
def test_a_missing_or_malformed_figure_leaves_its_part_out(tmp_path: Path, fast_plots: list[str], key: str) -> None:
    for i, replacement in enumerate((..., None, "text", [], {}, [None, "x"], float("nan"))):
        report = json.loads(json.dumps(REPORT))
        parent, _, name = key.rpartition(".")
        holder = report[parent] if parent else report
        if replacement is ...:
            del holder[name]
        else:
            holder[name] = replacement
        page = write_html_report(tmp_path / f"r{i}.html", tmp_path if i else _folder(tmp_path), report=report)
        text = _text(page)
        assert "\nSummary\n" in text and "Traceback" not in text
    if key in ("head_motion", "rest_pose"):
        assert {"head_motion": "\nHead motion\t", "rest_pose": "\nRest pose\t"}[key] not in text


@pytest.mark.parametrize("key", list(PERFORMANCE))
def test_an_older_performance_json_without_a_key_still_reports(tmp_path: Path, fast_plots: list[str],
                                                                key: str) -> None:
    performance = {k: v for k, v in PERFORMANCE.items() if k != key}
    text = _text(write_html_report(tmp_path / "r.html", _folder(tmp_path, performance), report=REPORT))
    assert "\nSummary\n" in text and "\nQuality\n" in text and "\nDetails\n" in text


def test_an_empty_folder_gives_only_the_summary(tmp_path: Path) -> None:
    text = _text(write_html_report(tmp_path / "r.html", tmp_path))
    assert "\nSummary\n" in text and f"\nResult folder\t{tmp_path}" in text
    assert not any(f"\n{h}\n" in text for h in ("Quality", "Warnings", "Notes", "Details"))


def test_the_muscle_solve_explains_its_flags(tmp_path: Path, fast_plots: list[str]) -> None:
    performance = {"rate": 60.0, "units": "mm", "n_frames": 4, "n_vertices": 900, "first_frame": 559,
                   "method": "sifakis2005-muscle-activations", "source_files": {"model": "/m/model"}}
    residual = [[1.0, 2.0, 6.5], [1.0, 1.5, 2.0], [0.5, 7.0, None], [1.0, 1.0, 1.0]]
    report = {"n_frames": 4, "first_frame": 559, "n_markers": 3, "n_tets": 5741, "n_muscles": 36,
              "marker_residual_mm": {"labels": ["a", "b", "c"], "per_frame": residual, "per_frame_max": [6.5, 2, 7, 1],
                                     "per_frame_rms": [4.0, 1.6, 5.0, 1.0], "max": 7.0, "rms": 3.2},
              "flags": {"559": ["large_residual"], "561": ["large_residual", "jaw_at_limit"]}, "frames_flagged": 2,
              "newton_iterations": [1, 2, 7, 1], "inverted_tets": [0, 0, 0, 0], "constraint_violation_max": 3e-6,
              "markers_left_out": ["Leye_Up"], "warnings": []}
    text = _text(write_html_report(tmp_path / "r.html", _folder(tmp_path, performance), report=report))
    assert "\tfacecap solve-muscles: " in text
    assert "\tmodel, 5,741 tetrahedra and 36 muscles" in text
    assert "\t3 on the face; 1 left out of the solve (Leye_Up)" in text
    assert "RMS 3.2 mm over the markers and frames, worst marker 7 mm (frame 561)" in text
    assert "2 of 4 frames flagged: 2 large residual, 1 jaw at limit" in text
    assert "jaw at limit: the jaw at the end of its range" in text
    assert "large residual: a marker farther from the simulated skin than the flag threshold" in text
    # per marker over the frames, the frames where it was not seen left out: c has 6.5, 2 and 1
    assert f"\nc\t{np.sqrt((6.5 ** 2 + 2 ** 2 + 1) / 3):.3g}\t6.5\t" in text
    assert "\nWarnings\tnone" in text and "\nWarnings\n" not in text


def test_every_muscle_frame_flag_is_explained() -> None:
    from facecap.muscles import FRAME_FLAGS

    assert set(html_report._MUSCLE_FLAGS) == set(FRAME_FLAGS)


def _write(folder: Path, name: str, document: dict[str, Any]) -> Path:
    folder.mkdir(exist_ok=True)
    (folder / name).write_text(json.dumps(document))
    return folder


def test_blend_edit_and_wrinkle_reports_show_their_own_figures(tmp_path: Path, fast_plots: list[str]) -> None:
    blend = _write(tmp_path / "blend", "performance.json", 
        {"rate": 60.0, "units": "mm", "n_frames": 3, "n_vertices": 10, "method": "huang2011-blendshapes",
         "planned_frames": [28, 47], "stabilized": True})
    _write(blend, "blend_report.json", 
        {"n_frames": 3, "n_bases": 2, "marker_residual_mm": {"per_frame": [0.1, 0.3, 0.2], "mean": 0.2, "max": 0.3},
         "head_pose_correction": {"rotation_deg": {"median": 0.01, "max": 0.03},
                                  "translation_mm": {"median": 0.1, "max": 0.57}}, "weights_s": 0.08})
    text = _text(write_html_report(blend / "report.html", blend))
    assert "\tfacecap blend: " in text and "\t2 scans, of take frames 28, 47" in text
    assert "mean 0.2 mm RMS, worst frame 0.3 mm (frame 1)" in text and "up to 0.03° and 0.57 mm" in text
    assert "\nBlend weights\t0.08 s" in text

    edit = _write(tmp_path / "edit", "performance.json", 
        {"rate": 60.0, "units": "mm", "n_frames": 2, "method": "sifakis2005-muscle-edit",
         "edit": {"kind": "sphere", "radius_mm": 10.0, "penetration_tolerance_mm": 0.05}})
    _write(edit, "report.json", 
        {"n_frames": 2, "frames": [3, 4], "converged": [True, False], "not_converged_frames": [4],
         "newton_iterations": [3, 9], "residual_mn": [0.001, 0.2],
         "skin_change_mm": {"per_frame_mean": [0.1, 0.2], "per_frame_max": [2.0, 3.5], "max": 3.5},
         "sphere": {"radius_mm": 10.0, "max_scan_penetration_mm": 0.02}})
    text = _text(write_html_report(edit / "report.html", edit))
    assert "\nEdit\tsphere" in text and "1 of 2 frames converged; not converged: frames 4" in text
    assert "largest 3.5 mm (frame 1)" in text and "deepest penetration of the skin 0.02 mm (tolerance 0.05 mm)" in text
    assert "\nEdit: radius\t10 mm" in text

    wrinkles = _write(tmp_path / "wrinkles", "performance.json", 
        {"rate": 50.0, "units": "mm", "n_frames": 9, "method": "bickel2007-medium-scale", "cameras": ["left", "right"],
         "footage": ["/f/left", "/f/right"], "video_rate_hz": 12.5, "large_scale": "/r/large"})
    frames = [{"video_frame": j, "wrinkles": [{"wrinkle": f"left:{k}", "drawn": False, "depth_mm": [0.2, -0.8 - j],
                                              "width_mm": [1.0, 1.2]} for k in range(3)]} for j in range(2)]
    _write(wrinkles, "wrinkles.json", {"units": "mm", "frames": frames})
    text = _text(write_html_report(wrinkles / "report.html", wrinkles))
    assert "\t2 cameras (left, right), video at 12.5 Hz" in text and "\tlarge\n" in text
    assert "3 wrinkles over 2 video frames (3 per frame), deepest 1.8 mm, median width 1.1 mm" in text



def test_a_blend_shows_each_scan_basis_and_marks_the_one_far_from_its_markers(tmp_path: Path,
                                                                              fast_plots: list[str]) -> None:
    blend = _write(tmp_path / "blend", "performance.json",
        {"rate": 60.0, "units": "mm", "n_frames": 3, "method": "huang2011-blendshapes", "planned_frames": [28, 47, 9]})
    basis = lambda i, frame, marker, mismatch: {  # noqa: E731
        "basis": i, "frame": frame, "scan": f"scan_{i}.obj", "registration_mm": 0.04,
        "marker_residual_mm": {"mean": marker, "max": 2 * marker}, "tangential_motion_mm": 1.2,
        "normal_motion_mm": 0.3, "colour_mismatch_by_round": mismatch, "colour_alignment_moved_mm": {"mean": 0.3}}
    _write(blend, "blend_report.json",
        {"n_frames": 3, "n_bases": 3, "marker_residual_mm": {"per_frame": [0.1, 0.3, 0.2], "mean": 0.2, "max": 0.3},
         "scan_bases": [{**basis(0, 28, 0.21, [0.11, 0.08]), "tangential_motion_mm": 0.0},
                        basis(1, 47, 0.25, [0.12, 0.085]), basis(2, 9, 1.9, [0.36, 0.35])]})
    text = _text(write_html_report(blend / "report.html", blend))
    assert "Scan bases" in text and "3 bases; markers disagree with their basis by 0.25 mm" in text
    rows = [line for line in text.splitlines() if line.startswith(("0\t", "1\t", "2\t"))]
    assert len(rows) == 3, rows
    assert rows[0].split("\t")[:6] == ["0", "28", "scan_0.obj", "0.04", "0.21", "0"] and "0.11 -> 0.08" in rows[0]
    assert not rows[0].endswith("look at this") and not rows[1].endswith("look at this")
    assert rows[2].endswith("look at this")  # 1.9 mm from its markers where the others are 0.2, texture unrelated


def test_review_link_and_pictures(tmp_path: Path, fast_plots: list[str]) -> None:
    folder = _folder(tmp_path)
    (folder / "review.html").write_text("<!doctype html>")
    imsave(folder / "activations.png", np.ones((4, 4, 3)))
    page = write_html_report(folder / "report.html", folder, report=REPORT, pictures=[folder / "activations.png"],
                             review_page=folder / "review.html")
    html = page.read_text()
    assert 'href="review.html"' in html
    assert "Muscle activations over the solved frames" in _text(page)
    # nothing but the review page is addressed: every other src is embedded
    addresses = re.findall(r'(?:src|href)="([^"]*)"', html)
    assert all(a.startswith("data:") or a == "review.html" for a in addresses), addresses


def test_sizes_numbers_and_durations_read_as_a_td_reads_them() -> None:
    assert [html_report._size(n) for n in (0, 999, 1000, 45_460, 1_374_774, 123_456_789, 2_500_000_000)] == \
        ["0 B", "999 B", "1 kB", "45.5 kB", "1.37 MB", "123 MB", "2.5 GB"]
    assert [html_report._duration(s) for s in (0.0701, 12.34, 75.0, 3725.0)] == \
        ["0.0701 s", "12.3 s", "1 min 15 s", "1 h 02 min"]
    assert [html_report._number(x) for x in (9409, 0.0106, 0.00048, 1.8e-6, 5608.2, 60.0)] == \
        ["9,409", "0.0106", "0.00048", "1.8e-06", "5,608", "60"]
    assert [html_report._label(k) for k in ("marker_residual_mm", "n_boundary_loops", "worst_frame_rms_mm", "gltf")] \
        == ["Marker residual", "Boundary loops", "Worst frame RMS", "glTF"]


def test_write_html_report_rejects_what_it_cannot_read(tmp_path: Path) -> None:
    from facecap.errors import InputError

    with pytest.raises(InputError, match="result folder not found"):
        write_html_report(tmp_path / "r.html", tmp_path / "missing")
    (tmp_path / "report.json").write_text("[1, 2]")
    with pytest.raises(InputError, match="expected a JSON object"):
        write_html_report(tmp_path / "r.html", tmp_path)
    (tmp_path / "picture.png").write_bytes(b"not a png")
    with pytest.raises(InputError, match="not a PNG"):
        write_html_report(tmp_path / "r.html", tmp_path, report={}, pictures=[tmp_path / "picture.png"])
    assert not (tmp_path / "r.html").exists()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        write_html_report(tmp_path / "r.html", tmp_path, report={})
