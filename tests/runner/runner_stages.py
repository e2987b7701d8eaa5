"""Stages for the frame runner's tests: deterministic, slow enough to interrupt, and logging their calls.

In a module of their own (not a test file) so that worker processes and the
subprocess of the interruption test import them by name.

Every call writes ``<start>-<pid>-<random>.start`` into ``log_dir`` when it
begins and the same name with ``.end`` when it returns: one small file each, so
two processes never write the same file, and the tests count calls (and see
which process was killed in the middle of one) without trusting the runner's
own account. ``log_dir`` is not a parameter: it does not change the frames.
"""

from __future__ import annotations

import os
import secrets
from pathlib import Path

import numpy as np


def reference_frame(seed: int, frame: int, n_values: int, iterations: int) -> np.ndarray:
    """One frame of :class:`SlowStage`, computed on its own: a seeded vector iterated through sin/cos.

    Elementwise ufuncs only (no BLAS), so the bytes do not depend on how many
    threads a process allows.
    """
    x = np.random.default_rng([seed, frame]).standard_normal(n_values)
    for _ in range(iterations):
        x = np.sin(1.7 * x) + 0.3 * np.cos(x + 0.001 * frame)
    return x


def _log(log_dir: str | None, start: int, kind: str, name: list[str]) -> None:
    if log_dir is None:
        return
    if not name:
        name.append(f"{start:06d}-{os.getpid()}-{secrets.token_hex(4)}")
    Path(log_dir, f"{name[0]}.{kind}").touch()


def calls(log_dir: str | os.PathLike[str], kind: str = "start") -> list[tuple[int, int]]:
    """``(chunk start, pid)`` of every call logged in ``log_dir`` (``kind`` 'start' or 'end')."""
    found = []
    for path in Path(log_dir).glob(f"*.{kind}"):
        start, pid, _ = path.stem.split("-")
        found.append((int(start), int(pid)))
    return sorted(found)


class SlowStage:
    """Independent frames, about ``iterations * 0.1`` ms each at 10,000 values."""

    def __init__(self, seed: int, *, n_values: int = 10_000, iterations: int = 200, log_dir: str | None = None):
        self.seed, self.n_values, self.iterations, self.log_dir = seed, n_values, iterations, log_dir

    def parameters(self) -> dict[str, int]:
        return {"seed": self.seed, "n_values": self.n_values, "iterations": self.iterations}

    def __call__(self, start: int, stop: int, state: object) -> tuple[dict[str, np.ndarray], None]:
        name: list[str] = []
        _log(self.log_dir, start, "start", name)
        values = np.stack([reference_frame(self.seed, f, self.n_values, self.iterations) for f in range(start, stop)])
        _log(self.log_dir, start, "end", name)
        return {"values": values, "frame": np.arange(start, stop, dtype=np.int64)}, None


def chain_step(x: np.ndarray, frame: int) -> np.ndarray:
    """One warm-started frame: the next state from the previous one (a contraction towards a moving target)."""
    target = np.sin(0.05 * frame + np.linspace(0.0, 3.0, x.size))
    return 0.5 * x + 0.5 * np.tanh(target + 0.2 * x)


class WarmStage:
    """Frames that depend on the previous frame: the state is the last frame, handed to the next chunk."""

    def __init__(self, n_values: int = 64, *, log_dir: str | None = None):
        self.n_values, self.log_dir = n_values, log_dir

    def parameters(self) -> dict[str, int]:
        return {"n_values": self.n_values}

    def __call__(self, start: int, stop: int, state: dict[str, np.ndarray] | None):
        name: list[str] = []
        _log(self.log_dir, start, "start", name)
        x = np.zeros(self.n_values) if state is None else state["x"]
        frames = []
        for frame in range(start, stop):
            x = chain_step(x, frame)
            frames.append(x)
        _log(self.log_dir, start, "end", name)
        return {"x": np.stack(frames)}, {"x": x}


class FailWhileFlagged:
    """Wrap a stage; raise on the chunk starting at ``fail_start`` while ``flag`` exists (an interruption)."""

    def __init__(self, inner: object, fail_start: int, flag: str):
        self.inner, self.fail_start, self.flag = inner, fail_start, flag

    def parameters(self) -> dict[str, int]:
        return self.inner.parameters()  # the flag does not change the frames

    def __call__(self, start: int, stop: int, state: object):
        if start == self.fail_start and os.path.exists(self.flag):
            raise RuntimeError(f"interrupted at frame {start}")
        return self.inner(start, stop, state)


class ExitsTheWorker:
    """A stage that kills the process running it (a segfault, the OOM killer)."""

    def parameters(self) -> dict[str, int]:
        return {}

    def __call__(self, start: int, stop: int, state: object):
        os._exit(3)
