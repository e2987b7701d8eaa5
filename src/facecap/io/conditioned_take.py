"""A conditioned take on disk: what ``plan-scans`` computed once, for ``register-scans`` and ``blend``.

Conditioning (gap filling, head stabilisation, filtering) is not free and,
with the consensus stabiliser, not a function of a few labels one could
replay. The scan workflow conditions a take once, writes the result here
beside ``plan.json``, and every later step reads it, so all of them see the
same markers and the same head motion.
"""

from __future__ import annotations

import hashlib
import json
import os
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FileFormatError
from ..structures import ConditionedTake
from .atomic_write import atomic_path

__all__ = ["file_sha256", "read_conditioned_take", "write_conditioned_take", "CONDITIONED_TAKE_FORMAT"]

CONDITIONED_TAKE_FORMAT = "facecap-conditioned-take"


def file_sha256(path: str | os.PathLike[str]) -> str:
    """Hex SHA-256 of a file's bytes: how a later step knows it was handed the same take."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def write_conditioned_take(
    path: str | os.PathLike[str],
    conditioned: ConditionedTake,
    *,
    labels: tuple[str, ...] | list[str],
    rate: float,
    settings: dict[str, Any],
    source_sha256: str | None,
) -> None:
    """Write a conditioned take as ``.npz`` (atomically).

    Parameters
    ----------
    path : path
        The ``.npz`` to write.
    conditioned : ConditionedTake
        From :func:`facecap.markers.condition_take`.
    labels : sequence of str
        The take's marker labels, in column order.
    rate : float
        Frame rate, Hz.
    settings : dict
        The conditioning options (JSON-ready), recorded for the record.
    source_sha256 : str or None
        :func:`file_sha256` of the raw take it was made from.
    """
    arrays: dict[str, Any] = {
        "positions": np.asarray(conditioned.positions, dtype=np.float64),
        "filled": np.asarray(conditioned.filled, dtype=bool),
        "labels": np.asarray(list(labels), dtype=str),
        "meta": np.asarray(json.dumps({"format": CONDITIONED_TAKE_FORMAT, "version": 1, "rate": float(rate),
                                       "settings": settings, "source_sha256": source_sha256,
                                       "stable_labels": list(conditioned.stable_labels),
                                       "temporal_sigma_s": conditioned.temporal_sigma_s})),
    }
    if conditioned.head_rotations is not None:
        arrays["head_rotations"] = np.asarray(conditioned.head_rotations, dtype=np.float64)
        arrays["head_translations"] = np.asarray(conditioned.head_translations, dtype=np.float64)
        arrays["stabilization_residual"] = np.asarray(conditioned.stabilization_residual, dtype=np.float64)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as handle:  # a handle, so numpy does not append .npz to the temporary name
            np.savez_compressed(handle, **arrays)


def read_conditioned_take(path: str | os.PathLike[str]) -> tuple[ConditionedTake, dict[str, Any]]:
    """Read a file written by :func:`write_conditioned_take`.

    Returns
    -------
    conditioned : ConditionedTake
    meta : dict
        ``labels`` (tuple of str), ``rate``, ``settings``, ``source_sha256``.

    Raises
    ------
    FileFormatError
        If the file is missing or not such a file.
    """
    p = Path(path)
    try:
        with np.load(p, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            if meta.get("format") != CONDITIONED_TAKE_FORMAT:
                raise ValueError("not a conditioned take")
            rotations = data["head_rotations"] if "head_rotations" in data.files else None
            conditioned = ConditionedTake(
                positions=data["positions"],
                filled=data["filled"],
                head_rotations=rotations,
                head_translations=data["head_translations"] if rotations is not None else None,
                stabilization_residual=data["stabilization_residual"] if rotations is not None else None,
                stable_labels=tuple(meta.get("stable_labels", ())),
                temporal_sigma_s=meta.get("temporal_sigma_s"),
            )
            meta["labels"] = tuple(str(s) for s in data["labels"])
    except FileNotFoundError:
        raise FileFormatError("the conditioned take is missing", path=str(p)) from None
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, json.JSONDecodeError) as exc:
        raise FileFormatError(f"not a facecap conditioned take ({exc})", path=str(p)) from None
    return conditioned, meta
