"""lights.json: round trips, units at the boundary, and one clear line for each malformed file."""

import json

import numpy as np
import pytest

from facecap.cameras import Light, LightSetup, read_light_file, write_light_file
from facecap.errors import FileFormatError


def _setup():
    return LightSetup((Light("spot", 2.0, [120.0, 300.0, 900.0], [-0.1, -0.3, -0.9], 25.0, 4.0, "key"),
                       Light("point", 0.2, [-500.0, 0.0, 700.0], name="fill"),
                       Light("directional", 0.1, direction=[0.0, -1.0, 0.0])), ambient=0.03)


def test_round_trip_is_exact(tmp_path):
    setup = _setup()
    write_light_file(tmp_path / "lights.json", setup)
    back = read_light_file(tmp_path / "lights.json")
    assert back.ambient == setup.ambient and back.source_unit == "mm"
    for a, b in zip(setup.lights, back.lights):
        assert a.describe() == b.describe()


def test_the_issues_example_reads_and_other_units_become_mm(tmp_path):
    path = tmp_path / "lights.json"
    path.write_text(json.dumps({"units": "cm", "lights": [{"type": "point", "position": [1, 2, 90], "intensity": 1.0}],
                                "ambient": 0.05}))
    setup = read_light_file(path)
    np.testing.assert_allclose(setup.lights[0].position, [10.0, 20.0, 900.0])
    assert setup.source_unit == "cm" and setup.ambient == 0.05


@pytest.mark.parametrize("document, message", [
    ("{not json", "not a JSON file"),
    ({"lights": [{"type": "point", "position": [0, 0, 1]}]}, "units"),
    ({"units": "mm", "lights": []}, "non-empty"),
    ({"units": "furlong", "lights": [{"type": "point", "position": [0, 0, 1]}]}, "unit"),
    ({"units": "mm", "lights": [{"type": "point"}]}, r"lights\[0\]: a point light needs a position"),
    ({"units": "mm", "lights": [{"type": "spot", "position": [0, 0, 1], "direction": [0, 0, -1]}]}, "cone_deg"),
    ({"units": "mm", "lights": [{"type": "point", "position": [0, 0, 1], "colour": 3}]}, "unknown keys"),
    ({"units": "mm", "lights": [{"type": "point", "position": [0, 0, 1]}], "ambient": -1}, "ambient"),
    ({"format": "facecap-cameras", "units": "mm", "lights": []}, "not a lights file"),
])
def test_malformed_files_name_the_file_and_the_problem(tmp_path, document, message):
    path = tmp_path / "lights.json"
    path.write_text(document if isinstance(document, str) else json.dumps(document))
    with pytest.raises(FileFormatError, match=message) as info:
        read_light_file(path)
    assert "lights.json" in str(info.value)


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(FileFormatError, match="not found"):
        read_light_file(tmp_path / "nope.json")
