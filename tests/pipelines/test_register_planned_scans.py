"""register-scans refuses bad inputs in one line, before it writes anything."""

import json

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
