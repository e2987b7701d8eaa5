import json

import pytest

from facecap.errors import FileFormatError, InputError
from facecap.io.scan_plan import read_scan_plan, write_scan_plan


def test_round_trip_and_frames_checked_against_the_take(tmp_path):
    path = tmp_path / "plan.json"
    write_scan_plan(path, {"frames": [12, 3, 40], "times_s": [0.2, 0.05, 0.67]},
                    conditioning={"rest_frame": 0, "stable_markers": ["HB0"], "smooth": True}, source="take.c3d")
    plan = read_scan_plan(path, n_frames=41)
    assert plan["frames"] == [12, 3, 40] and plan["conditioning"]["stable_markers"] == ["HB0"]
    with pytest.raises(InputError, match=r"\[40\] do not exist"):
        read_scan_plan(path, n_frames=40)


@pytest.mark.parametrize("content", ["not json", json.dumps({"frames": []}), json.dumps({"frames": [1, 1]}),
                                     json.dumps({"frames": [1.5]}), json.dumps([1, 2])])
def test_malformed_plans(tmp_path, content):
    path = tmp_path / "plan.json"
    path.write_text(content)
    with pytest.raises(FileFormatError):
        read_scan_plan(path)
