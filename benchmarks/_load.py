"""Timing a block of work on a shared machine: wall time plus the CPU other processes took meanwhile."""

from __future__ import annotations

import os
import resource
import time
from typing import Any


def _busy_jiffies() -> int:
    """Busy CPU time of the whole machine so far, in clock ticks (from /proc/stat)."""
    with open("/proc/stat") as f:
        fields = [int(x) for x in f.readline().split()[1:]]
    user, nice, system, _idle, _iowait, irq, softirq, steal = fields[:8]
    return user + nice + system + irq + softirq + steal


class Window:
    """Wall time of a ``with`` block, plus the CPU (in cores) this process and others used meanwhile.

    After the block: ``seconds``, ``my_cores`` (this process's user+system time
    per second of wall time) and ``other_cores`` (the rest of the machine's busy
    time per second), so a figure measured while others ran can be told apart.
    """

    def __enter__(self) -> Window:  # noqa: PYI034
        self._hz = os.sysconf("SC_CLK_TCK")
        t = os.times()
        self._mine = t.user + t.system
        self._busy = _busy_jiffies()
        self._t = time.perf_counter()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.seconds = time.perf_counter() - self._t
        t = os.times()
        mine = t.user + t.system - self._mine
        busy = (_busy_jiffies() - self._busy) / self._hz
        self.my_cores = mine / max(self.seconds, 1e-9)
        self.other_cores = max(busy - mine, 0.0) / max(self.seconds, 1e-9)


def peak_rss_gb() -> float:
    """Peak resident memory of this process so far, GB (10^9 bytes); ``ru_maxrss`` is in KiB on Linux."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e9
