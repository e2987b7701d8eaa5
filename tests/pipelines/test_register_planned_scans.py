"""register-scans refuses bad inputs in one line, before it writes anything."""

import json

import pytest

from facecap.cli import main


def test_bad_inputs_are_clear_errors(scan_workflow, capsys):
    root, case, files, frames, scans = scan_workflow
    plan = json.loads((root / "plan.json").read_text())
    bad_plan = root / "bad_plan.json"
    bad_plan.write_text(json.dumps({**plan, "frames": [5, 4000]}))
    args = ["-q", "register-scans", "--markers", str(files.markers), "--template", str(files.scan)]
    capsys.readouterr()
    assert main([*args, "--plan", str(bad_plan), "--scans", *scans[:2], "--out", str(root / "x")]) == 2
    assert "4000" in capsys.readouterr().err
    assert main([*args, "--plan", str(root / "plan.json"), "--scans", *scans[:-1], "--out", str(root / "x")]) == 2
    assert "one scan per planned frame" in capsys.readouterr().err
    assert main([*args, "--plan", str(root / "plan.json"), "--scans", *scans, "--scan-units", "m",
                 "--out", str(root / "x")]) == 2
    assert "units" in capsys.readouterr().err
    assert not (root / "x").exists()


def test_colour_alignment_is_chosen_when_every_scan_and_the_template_show_the_skin():
    import numpy as np

    from facecap.errors import FacecapWarning
    from facecap.pipelines import colour_alignment_choice
    from facecap.structures import Mesh

    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    F = np.array([[0, 1, 2]])
    uv = dict(uvs=V[:, :2], uv_indices=F.ravel())
    textured = Mesh(V, F, texture=np.zeros((2, 2, 3), np.uint8), **uv)
    coloured = Mesh(V, F, vertex_colors=np.zeros((3, 3)))
    bare = Mesh(V, F)
    assert colour_alignment_choice(None, [textured, textured], textured, None)[0] is True
    assert colour_alignment_choice(None, [textured, textured], None, None)[0] is True  # the first scan is the template
    assert colour_alignment_choice(None, [textured], bare, textured)[0] is True  # --template-texture
    # some textured, some not (a texture lost on the way, UVs on one point): off, and said so
    flat = Mesh(V, F, texture=np.zeros((2, 2, 3), np.uint8), uvs=np.full((3, 2), 0.3), uv_indices=F.ravel(),
                source_path="scan_07.obj")
    for scans, template, named in (([textured, coloured], textured, "scan 1"), ([textured], bare, "the template"),
                                   ([textured, flat, bare], textured, "scan_07.obj")):
        with pytest.warns(FacecapWarning, match=f"colour alignment off: {named}: .* geometry alone"):
            on, why = colour_alignment_choice(None, scans, template, None)
        assert on is False and why.startswith(named)
    assert "cover no texels" in why and "1 more" in why
    assert colour_alignment_choice(None, [coloured], coloured, None) == (False, "the scans or the template have no "
                                                                        "colour texture")
    assert colour_alignment_choice(True, [coloured], coloured, None) == (True, "asked for")
    assert colour_alignment_choice(False, [textured], textured, None) == (False, "turned off")
