"""Tests for facecap/pipelines/calibrate_stage_light.py: footage of a chrome sphere in, lights.json out."""

import numpy as np
import pytest

from facecap.cameras import read_image, read_light_file, write_image_sequence
from facecap.errors import FacecapWarning, InputError
from facecap.pipelines import calibrate_stage_light, light_check_path
from facecap.synth.mirror_sphere import render_mirror_sphere
from mirror_sphere_stage import SPHERE_RADIUS_MM, stage


def write_sphere_footage(folder, st, *, n=None):
    """One image folder per camera (named after it), a frame per sphere position; the folders' paths."""
    rng = np.random.default_rng(0)
    frames = [[] for _ in st.cameras]
    for centre in st.positions[:n]:
        for k, image in enumerate(render_mirror_sphere(st.cameras, centre, SPHERE_RADIUS_MM, st.light, rng=rng)):
            frames[k].append(image)
    paths = []
    for camera, images in zip(st.cameras, frames):
        write_image_sequence(folder / camera.name, np.stack(images))
        paths.append(folder / camera.name)
    return paths


def test_writes_the_light_and_its_picture(tmp_path):
    st = stage(5, n_positions=4)
    paths = write_sphere_footage(tmp_path, st)
    out = tmp_path / "lights.json"
    done = calibrate_stage_light(st.cameras, paths, SPHERE_RADIUS_MM, out, intensity=2.0, ambient=0.1)
    setup = read_light_file(out)
    assert setup.ambient == 0.1 and len(setup.lights) == 1
    light = setup.lights[0]
    assert light.kind == "point" and light.intensity == 2.0
    np.testing.assert_allclose(light.position, done.light.position)
    assert np.linalg.norm(light.position - st.light.position) < 0.03 * np.linalg.norm(st.light.position)
    picture = read_image(light_check_path(out))
    assert picture.shape == (480, 1280, 3) and picture.dtype == np.uint8


def test_one_position_warns_and_bad_footage_writes_nothing(tmp_path):
    st = stage(5, n_positions=2)
    paths = write_sphere_footage(tmp_path, st, n=1)
    out = tmp_path / "lights.json"
    with pytest.warns(FacecapWarning, match="weak geometry"):
        done = calibrate_stage_light(st.cameras, paths, SPHERE_RADIUS_MM, out)
    assert done.light.kind == "directional" and read_light_file(out).lights[0].kind == "directional"
    with pytest.raises(InputError, match="exists"):
        calibrate_stage_light(st.cameras, paths, SPHERE_RADIUS_MM, out)
    # a frame without the sphere: the error names that image file; nothing is written
    dark = tmp_path / "dark"
    write_image_sequence(dark, np.zeros((1, 480, 640, 3), np.uint8))
    other = tmp_path / "other.json"
    with pytest.raises(InputError, match=r"dark/.*no sphere found"):
        calibrate_stage_light(st.cameras, [dark, paths[1]], SPHERE_RADIUS_MM, other)
    assert not other.exists() and not light_check_path(other).exists()
    with pytest.raises(InputError, match="1 footage for 2 cameras"):
        calibrate_stage_light(st.cameras, paths[:1], SPHERE_RADIUS_MM, other)
