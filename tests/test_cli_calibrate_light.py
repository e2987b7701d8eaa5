"""Tests of ``facecap calibrate-light`` (cli.py): the light printed and written; bad input is one line, exit 2."""

import numpy as np

from facecap.cameras import CameraSetup, read_light_file, write_camera_file, write_image_sequence
from facecap.cli import main
from mirror_sphere_stage import SPHERE_RADIUS_MM, stage
from pipelines.test_calibrate_stage_light import write_sphere_footage


def test_calibrate_light_command(tmp_path, capsys):
    st = stage(6, n_positions=3)
    paths = write_sphere_footage(tmp_path, st)
    write_camera_file(tmp_path / "cameras.json", CameraSetup(tuple(st.cameras)))
    out = tmp_path / "lights.json"
    args = ["calibrate-light", "--cameras", str(tmp_path / "cameras.json"), "--images", *map(str, paths),
            "--sphere-radius", str(SPHERE_RADIUS_MM), "--out", str(out)]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "point light at" in printed and "ray distances: rms" in printed and "lights_check.png" in printed
    light = read_light_file(out).lights[0]
    assert np.linalg.norm(light.position - st.light.position) < 0.05 * np.linalg.norm(st.light.position)
    # bad input: one line naming the problem, exit 2, nothing replaced
    before = out.read_text()
    assert main(args[:-2] + ["--out", str(out), "--overwrite", "--sphere-radius", "0"]) == 2
    write_image_sequence(tmp_path / "dark", np.zeros((3, 480, 640, 3), np.uint8))
    assert main(args[:4] + [str(tmp_path / "dark"), str(paths[1]), "--sphere-radius", "40", "--out",
                            str(tmp_path / "x.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and err[0].startswith("facecap: error: --sphere-radius")
    assert err[1].startswith(f"facecap: error: {tmp_path / 'dark'}") and "no sphere found" in err[1]
    assert out.read_text() == before and not (tmp_path / "x.json").exists()
