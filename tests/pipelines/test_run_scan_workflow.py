"""facecap scans-pipeline end to end through the CLI (the job: facecap/pipelines/run_scan_workflow.py): the
planned scans registered and the take blended into one folder, and what it would replace refused first."""

import json

import numpy as np

from facecap.cli import main


def test_the_scans_are_registered_and_blended_into_one_folder(scan_workflow, tmp_path, capsys):
    root, case, files, frames, scans = scan_workflow
    plan = root / "plan.json"
    plan_before = plan.read_bytes()
    out = tmp_path / "run"
    args = ["scans-pipeline", "--markers", str(files.markers), "--scans", *scans, "--plan", str(plan),
            "--template", str(files.scan), "--out", str(out)]
    assert main(["-q", *args]) == 0
    assert plan.read_bytes() == plan_before and not (out / "plan.json").exists()  # the plan given is used as is
    report = json.loads((out / "bases" / "bases.json").read_text())["report"]
    assert len(report["registration_mm"]) == len(frames) and max(report["registration_mm"]) < 0.2
    V = np.load(out / "animation" / "vertices.npy", mmap_mode="r")
    assert V.shape == case.truth_vertices.shape
    err = np.linalg.norm(V[frames] - case.truth_vertices[frames], axis=2).mean()
    neutral = np.linalg.norm(case.scan.vertices[None] - case.truth_vertices[frames], axis=2).mean()
    assert err < 0.5 * neutral  # at the scanned frames the blend is the scanned expressions
    # a second run is refused at once, one line, changing nothing
    capsys.readouterr()
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*")}
    assert main(args) == 2
    err_lines = capsys.readouterr().err.strip().splitlines()
    assert len(err_lines) == 1 and "pass --overwrite" in err_lines[0]
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*")} == before
    # an unknown export is refused before any step starts
    fresh = tmp_path / "fresh"
    assert main([*args[:-1], str(fresh), "--export", "nope"]) == 2
    err_lines = capsys.readouterr().err.strip().splitlines()
    assert len(err_lines) == 1 and "--export" in err_lines[0] and not fresh.exists()
