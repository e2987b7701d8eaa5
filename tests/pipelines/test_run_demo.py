"""facecap demo through the command line (the job: facecap/pipelines/run_demo.py), on a short generated take."""

import json

import numpy as np
from matplotlib.image import imread

from facecap.cli import main
from recorded_paths import assert_recorded_paths_are_final


def test_demo_writes_the_animation_report_and_pictures(tmp_path, capsys):
    out = tmp_path / "facecap-demo"
    assert main(["--quiet", "demo", "--out", str(out), "--frames", "120"]) == 0
    summary = json.loads((out / "demo_summary.json").read_text())
    shell = summary["generated_take"]["thin_shell"]
    warp = summary["generated_take"]["warp_alone"]
    assert shell["mean_mm"] < 0.8 and shell["mean_mm"] <= warp["mean_mm"]
    V = np.load(out / "animation" / "vertices.npy", mmap_mode="r")
    assert V.shape == (120, 9409, 3)
    assert (out / "animation" / "performance.usdc").is_file()
    # the review the summary points to: the glTF, its page with the truth's heat map, the report linking it
    assert (out / "animation" / "performance.glb").is_file()
    assert '"error":{"n":' in (out / "animation" / "review.html").read_text()  # the heat map is in the page
    assert 'href="review.html"' in (out / "animation" / "report.html").read_text()
    assert summary["animface_take"]["max_flipped_triangles_in_any_frame"] == 0
    scans = summary["scan_workflow"]
    errors = scans["error_after_each_mm"]
    assert all(b <= a + 1e-9 for a, b in zip(errors, errors[1:]))  # Fig. 8: monotone in the number of scans
    assert max(scans["registration_mm"]) < 0.2
    # the blended scans against the generator's ground truth: better than the thin shell on the same take
    assert scans["blend"]["mean_mm"] < shell["mean_mm"]
    # the methods are compared at a frame that was not scanned (a scanned frame is the blend's own basis), on the
    # colour scale of frame_comparison.png: the range each picture was drawn with, as render_side_by_side returned it
    assert scans["compared_frame"] not in scans["planned_frames"]
    ranges = summary["picture_colour_ranges_mm"]
    assert ranges["methods_error_comparison.png"] == ranges["frame_comparison.png"]
    # the muscle-driven face on the real take: physics holds (no inverted element, activations in [0, 1])
    muscles = summary["muscles"]
    assert muscles["inverted_tets_max"] == 0 and 0.0 < muscles["activation_max"] <= 1 + 1e-4
    assert muscles["markers_left_out"] == ["Leye_Up", "Reye_Up"]  # the eyelids: off the model
    activations = np.loadtxt(out / "muscles" / "animface" / "activations.csv", delimiter=",", skiprows=1)[:, 1:]
    assert activations.shape == (96, muscles["muscles"]) and activations.min() >= -1e-4
    # the summary says what "flagged" means: every flag counted, with its meaning
    flags = muscles["flags"]
    assert sum(f["frames"] for f in flags.values()) >= muscles["frames_flagged"] > 0
    assert flags["large_residual"]["meaning"].startswith("a marker more than 5 mm from the model")
    # the wrinkle layer's large scale carries the frame's whole expression (a rest pose averaged over the take's
    # first 13 frames took half the smile into it: 0.83 of the expression's own size, against 0.24 now)
    from facecap.io.read_result import read_result

    truth = np.load(out / "wrinkles" / "inputs" / "truth.npz")
    large = read_result(out / "wrinkles" / "large_scale").frames(8, 9)[0].astype(np.float64)
    expression = np.linalg.norm(truth["large_scale"][8] - truth["large_scale"][0], axis=1).mean()
    off = np.linalg.norm(large - truth["large_scale"][8], axis=1).mean()
    assert off < 0.4 * expression
    wrinkles = summary["wrinkles"]
    assert wrinkles["cross_section"]["wrinkle"] in [str(n) for n in truth["curve_names"]]
    for name in ("frame_comparison.png", "dense_error_over_time.png", "marker_residuals.png",
                 "scan_selection.png", "methods_error_comparison.png", "methods_error_over_time.png",
                 "muscles_layout.png", "muscles_activations.png", "muscles_frame_comparison.png",
                 "wrinkles_frame.png", "wrinkles_error.png", "wrinkles_cross_section.png",
                 "wrinkles_tracked_splines.png"):
        image = imread(out / "pictures" / name)
        assert image.ndim == 3 and image.std() > 0.01  # a picture, not a blank canvas
    # no staging folder is left behind (a second run replacing this one is atomic_folder's, tested in
    # tests/io/test_atomic_write.py: running the whole demo twice here cost two minutes)
    assert [p.name for p in tmp_path.iterdir()] == ["facecap-demo"]
    # every path its files record is final and there: edit-muscles finds the model the take was solved on
    assert assert_recorded_paths_are_final(out) > 50
    solved = json.loads((out / "muscles" / "animface" / "performance.json").read_text())
    assert solved["source_files"]["model"] == str((out / "muscles" / "model").resolve())
    # a second run is refused at once (one line saying what to pass), and changes nothing
    capsys.readouterr()
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*")}
    assert main(["demo", "--out", str(out), "--frames", "120"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(out) in err[0] and "pass --overwrite" in err[0]
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*")} == before
    assert [p.name for p in tmp_path.iterdir()] == ["facecap-demo"]
