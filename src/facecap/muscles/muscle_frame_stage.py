"""The muscle solve as a frame-runner stage: chunks of a take solved frame by frame, each warm-started.

:class:`MuscleFrameStage` is what :func:`~facecap.runner.run_frames` calls for every chunk
(``stage(start, stop, state)``, see ``docs/runner.md``). It reads the anatomy model folder and
builds the :class:`~facecap.muscles.MuscleSolver` once per process (a module-level cache keyed
by the stage's parameters), then solves the chunk's frames in order, each from the one before.
A chunk's first frame is solved cold (from rest, with the paper's extra Gauss-Newton steps)
unless the previous chunk of its segment handed over its last frame as ``state``.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any, Mapping

import numpy as np
from threadpoolctl import threadpool_limits

from ..errors import FileFormatError, InputError
from ..typing import FloatArray
from .muscle_solver import MuscleFrame, MuscleSolver

__all__ = ["MuscleFrameStage", "FRAME_FLAGS", "FRAME_FLAG_MEANINGS", "flag_names", "model_folder_sha256"]

FRAME_FLAGS = ("too_few_markers", "inverted_tets", "not_converged", "constraint_violation", "jaw_at_limit",
               "large_residual")
"""The :class:`MuscleFrame` flags, in bit order: bit ``i`` of the stage's ``flags`` is ``FRAME_FLAGS[i]``."""
FRAME_FLAG_MEANINGS = {
    "too_few_markers": "fewer than 6 markers seen: not solved, the previous controls carried",
    "inverted_tets": "a tetrahedron of the solved flesh is inverted",
    "not_converged": "a quasistatic solve missed its tolerance",
    "constraint_violation": "an activation, bone rigidity or jaw constraint violated by more than 1e-4",
    "jaw_at_limit": "the jaw at its largest opening or slide: the markers may ask for more than the joint allows",
    "large_residual": "a marker more than 5 mm from the model (flag_residual_mm): the model does not reach "
                      "the markers there",
}
"""What each flag says, in a line a summary can print (:class:`MuscleFrame`'s ``flags``)."""

# per process: the opened models and the solvers built on them (a solver costs the flesh model's
# set-up; a chunk costs seconds per frame, so each worker builds it once, not once per chunk)
_ANATOMIES: dict[str, Any] = {}
_SOLVERS: dict[str, MuscleSolver] = {}


def flag_names(bits: int) -> tuple[str, ...]:
    """The flag names of a ``flags`` bit mask (:data:`FRAME_FLAGS` order)."""
    return tuple(name for i, name in enumerate(FRAME_FLAGS) if int(bits) >> i & 1)


def _sha256(*arrays: np.ndarray) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def model_folder_sha256(model_dir: str | Path) -> str:
    """SHA-256 of a model folder's ``anatomy.npz`` and ``anatomy.json`` (what the frames depend on)."""
    h = hashlib.sha256()
    for name in ("anatomy.npz", "anatomy.json"):
        path = Path(model_dir) / name
        if not path.is_file():
            raise FileFormatError("missing; not an anatomy folder written by build-anatomy", path=str(path))
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    return h.hexdigest()


class MuscleFrameStage:
    """Muscle activations, cranium and jaw for a range of frames: a frame-runner stage.

    Picklable and deterministic: a pure function of ``(start, stop, state)`` (the solver is
    rebuilt per process from the model folder, never carried between calls except as a
    cache of the same set-up; a repeated solve at the same controls and state returns the
    same solution).

    Parameters
    ----------
    model_dir : str or path-like
        An anatomy model folder (``facecap build-anatomy``: ``anatomy.npz``, ``anatomy.json``).
        On a cluster, every worker must see it at the same path.
    marker_vertices : (M,) int array
        Scan vertex under each marker.
    rest_markers : (M, 3) float64 array, mm
        The markers at rest, in the scan's coordinates (:class:`MuscleSolver`).
    markers : (T, M, 3) float64 array, mm
        The take (world coordinates), NaN for a missing marker. Frame ``j`` of the run is
        ``markers[j]``.
    options : mapping, optional
        :class:`MuscleSolver` options (``max_steps``, ``max_warm_steps``, ``marker_noise_mm``,
        ``solve_cranium``, ``rim``, ...): JSON values only.
    model_sha256 : str, optional
        The model folder's :func:`model_folder_sha256` (computed here if not given).

    Notes
    -----
    ``stage(start, stop, state)`` returns per frame, frame-major:

    ==========================  ==================  ==========================================
    name                        dtype, shape        meaning
    ==========================  ==================  ==========================================
    ``vertices``                float32 (n, 3)      the skin at the scan's vertices, world, mm
    ``activations``             float64 (k,)        in [0, 1]
    ``cranium``, ``mandible``   float64 (3, 4)      :class:`MuscleControls` frames, mm
    ``jaw_pose``                float64 (3,)        opening (rad), slide left, right (mm)
    ``marker_residual``         float64 (M,)        model to observed marker, mm; NaN if missing
    ``rms_mm``                  float64 ()          over the observed markers
    ``flags``                   int32 ()            bit mask, :data:`FRAME_FLAGS` order
    ``steps``                   int32 ()            Gauss-Newton steps
    ``quasistatic_solves``      int32 ()            equilibria solved
    ``newton_iterations``       int32 ()            summed over those solves
    ``inverted_tets``           int32 ()            in the solved state
    ``constraint_violation``    float64 ()          largest of :attr:`MuscleFrame.constraint_violation`
    ``cold``                    bool ()             solved from rest (a chunk's first frame)
    ==========================  ==================  ==========================================

    and as state the last frame (``activations``, ``cranium``, ``mandible``, ``nodes``), from
    which the next chunk of a segment continues exactly as one loop would.
    """

    def __init__(self, model_dir: str | Path, marker_vertices: Any, rest_markers: Any, markers: Any, *,
                 options: Mapping[str, Any] | None = None, model_sha256: str | None = None) -> None:
        self.model_dir = str(Path(model_dir).resolve())
        self.marker_vertices = np.asarray(marker_vertices, dtype=np.int64).reshape(-1)
        self.rest_markers = np.asarray(rest_markers, dtype=np.float64)
        self.markers = np.asarray(markers, dtype=np.float64)
        M = self.marker_vertices.size
        if self.rest_markers.shape != (M, 3):
            raise InputError(f"rest_markers: expected shape ({M}, 3), got {self.rest_markers.shape}")
        if self.markers.ndim != 3 or self.markers.shape[1:] != (M, 3) or self.markers.shape[0] < 1:
            raise InputError(f"markers: expected shape (T, {M}, 3) with T >= 1, got {self.markers.shape}")
        self.options = dict(options or {})
        try:
            json.dumps(self.options, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise InputError(f"options: expected JSON values (numbers, strings, booleans), {exc}") from None
        self.model_sha256 = model_sha256 if model_sha256 is not None else model_folder_sha256(self.model_dir)

    @property
    def n_frames(self) -> int:
        """Frames of the take."""
        return int(self.markers.shape[0])

    def parameters(self) -> dict[str, Any]:
        """What the frames depend on (the runner refuses to resume a run with other values)."""
        return {"model_dir": self.model_dir, "model_sha256": self.model_sha256,
                "marker_vertices": self.marker_vertices.tolist(),
                "rest_markers_sha256": _sha256(self.rest_markers), "markers_sha256": _sha256(self.markers),
                "n_frames": self.n_frames, "options": dict(sorted(self.options.items()))}

    def _key(self) -> str:
        p = self.parameters()
        return json.dumps({k: p[k] for k in ("model_dir", "model_sha256", "marker_vertices",
                                             "rest_markers_sha256", "options")}, sort_keys=True)

    def solver(self) -> MuscleSolver:
        """The solver of this stage's model, markers and options, built once per process."""
        key = self._key()
        solver = _SOLVERS.get(key)
        if solver is None:
            from ..anatomy import load_anatomy

            anatomy_key = f"{self.model_dir}:{self.model_sha256}"
            anatomy = _ANATOMIES.get(anatomy_key)
            if anatomy is None:
                anatomy = _ANATOMIES[anatomy_key] = load_anatomy(self.model_dir)
            solver = _SOLVERS[key] = MuscleSolver(anatomy, self.marker_vertices, self.rest_markers, **self.options)
        return solver

    def _previous(self, solver: MuscleSolver, state: Mapping[str, np.ndarray]) -> MuscleFrame:
        """A :class:`MuscleFrame` carrying what a warm start reads: the controls and the nodes."""
        try:
            a, cranium = np.asarray(state["activations"]), np.asarray(state["cranium"])
            mandible, nodes = np.asarray(state["mandible"]), np.asarray(state["nodes"])
        except KeyError as exc:
            raise InputError(f"state: expected activations, cranium, mandible and nodes, missing {exc}") from None
        nan = np.full(solver.n_markers, np.nan)
        return MuscleFrame(activations=a, cranium=cranium, mandible=mandible, jaw_pose=np.zeros(3), nodes=nodes,
                           skin=np.empty((0, 3)), markers=np.empty((0, 3)), marker_residuals=nan,
                           rms_mm=float("nan"), steps=0, quasistatic_solves=0, newton_iterations=0, inverted_tets=0)

    def solve(self, start: int, stop: int, previous: MuscleFrame | None = None) -> list[MuscleFrame]:
        """Frames ``start .. stop - 1`` solved in order, the first from ``previous`` (None: cold).

        One BLAS and MKL thread (PARDISO included), as on a Dask worker: a
        multithreaded factorisation rounds differently from run to run, and a
        chunk computed twice (a resumed run, a lost worker) must give the same bytes.
        """
        if not (0 <= start < stop <= self.n_frames):
            raise InputError(f"frames {start}..{stop}: expected 0 <= start < stop <= {self.n_frames}")
        with threadpool_limits(limits=1):
            solver = self.solver()
            frames = []
            for t in range(start, stop):
                previous = solver.solve_frame(self.markers[t], previous)
                frames.append(previous)
        return frames

    def __call__(self, start: int, stop: int, state: Mapping[str, np.ndarray] | None
                 ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        solver = self.solver()
        previous = None if state is None else self._previous(solver, state)
        frames = self.solve(start, stop, previous)
        bits = {name: 1 << i for i, name in enumerate(FRAME_FLAGS)}
        arrays = {
            "vertices": np.stack([f.skin for f in frames]).astype(np.float32),
            "activations": np.stack([f.activations for f in frames]),
            "cranium": np.stack([f.cranium for f in frames]),
            "mandible": np.stack([f.mandible for f in frames]),
            "jaw_pose": np.stack([f.jaw_pose for f in frames]),
            "marker_residual": np.stack([f.marker_residuals for f in frames]),
            "rms_mm": np.array([f.rms_mm for f in frames], dtype=np.float64),
            "flags": np.array([sum(bits.get(name, 0) for name in f.flags) for f in frames], dtype=np.int32),
            "steps": np.array([f.steps for f in frames], dtype=np.int32),
            "quasistatic_solves": np.array([f.quasistatic_solves for f in frames], dtype=np.int32),
            "newton_iterations": np.array([f.newton_iterations for f in frames], dtype=np.int32),
            "inverted_tets": np.array([f.inverted_tets for f in frames], dtype=np.int32),
            "constraint_violation": np.array([max(f.constraint_violation.values(), default=0.0) for f in frames],
                                             dtype=np.float64),
            "cold": np.array([previous is None] + [False] * (len(frames) - 1), dtype=bool),
        }
        last = frames[-1]
        state_out: dict[str, FloatArray] = {"activations": last.activations, "cranium": last.cranium,
                                            "mandible": last.mandible, "nodes": last.nodes}
        return arrays, state_out
