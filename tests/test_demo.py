import json

import numpy as np
from matplotlib.image import imread

from facecap.cli import main


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
    # the muscle-driven face on the real take: physics holds (no inverted element, activations in [0, 1])
    muscles = summary["muscles"]
    assert muscles["inverted_tets_max"] == 0 and 0.0 < muscles["activation_max"] <= 1 + 1e-4
    assert muscles["markers_left_out"] == ["Leye_Up", "Reye_Up"]  # the eyelids: off the model
    activations = np.loadtxt(out / "muscles" / "animface" / "activations.csv", delimiter=",", skiprows=1)[:, 1:]
    assert activations.shape == (96, muscles["muscles"]) and activations.min() >= -1e-4
    for name in ("frame_comparison.png", "dense_error_over_time.png", "marker_residuals.png",
                 "scan_selection.png", "methods_error_comparison.png", "methods_error_over_time.png",
                 "muscles_layout.png", "muscles_activations.png", "muscles_frame_comparison.png"):
        image = imread(out / "pictures" / name)
        assert image.ndim == 3 and image.std() > 0.01  # a picture, not a blank canvas
    # no staging folder is left behind (a second run replacing this one is atomic_folder's, tested in
    # tests/io/test_atomic.py: running the whole demo twice here cost two minutes)
    assert [p.name for p in tmp_path.iterdir()] == ["facecap-demo"]
