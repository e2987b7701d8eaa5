"""The tests' install lock: a second process waits until the first has finished (the workers share tools)."""

import subprocess
import sys
import time
from pathlib import Path

from tool_install import install_lock

HOLD_S = 1.0


def test_a_second_process_waits_for_the_install_in_progress(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("FACECAP_TEST_CACHE", str(tmp_path))
    log = tmp_path / "log.txt"
    first = subprocess.Popen(
        [sys.executable, "-c",
         "import sys, time; sys.path.insert(0, sys.argv[1]); from tool_install import install_lock\n"
         "with install_lock('tool'):\n"
         "    with open(sys.argv[2], 'a') as f: f.write('first in\\n')\n"
         "    time.sleep(float(sys.argv[3]))\n"
         "    with open(sys.argv[2], 'a') as f: f.write('first out\\n')\n",
         str(Path(__file__).parent), str(log), str(HOLD_S)],
    )
    deadline = time.monotonic() + 30
    while not log.exists():  # the first process holds the lock once it has written
        assert first.poll() is None, "the first process ended before it took the lock"
        assert time.monotonic() < deadline, "the first process never took the lock"
        time.sleep(0.01)
    with install_lock("tool"), log.open("a") as f:
        f.write("second in\n")
    assert first.wait(timeout=30) == 0
    assert log.read_text().splitlines() == ["first in", "first out", "second in"]
