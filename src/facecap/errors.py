"""Exceptions and warnings raised by facecap.

Every error caused by bad input derives from :class:`FacecapError`; the command
line turns these into one line naming the file and the problem and a non-zero
exit. Errors about bad values also derive from :class:`ValueError` so that
library callers can catch them the ordinary way.
"""

from __future__ import annotations

__all__ = [
    "FacecapError",
    "InputError",
    "FileFormatError",
    "MeshError",
    "MarkerError",
    "CorrespondenceError",
    "SolverError",
    "FacecapWarning",
]


class FacecapError(Exception):
    """Base class of every error facecap raises on purpose.

    Parameters
    ----------
    message : str
        What is wrong, naming the argument or file.
    path : str or None, optional
        The file the problem was found in, if any; the CLI prints it first.
    """

    def __init__(self, message: str, *, path: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.path = path

    def __str__(self) -> str:
        if self.path:
            return f"{self.path}: {self.message}"
        return self.message


class InputError(FacecapError, ValueError):
    """An argument has the wrong shape, type, range or content."""


class FileFormatError(InputError):
    """A file is missing, truncated, corrupt or not in the expected format."""


class MeshError(InputError):
    """A mesh cannot be used as given (faces out of range, no faces, ...)."""


class MarkerError(InputError):
    """A marker sequence cannot be used as given (too few markers, all gaps, ...)."""


class CorrespondenceError(InputError):
    """A marker-to-scan map names markers or vertices that do not exist."""


class SolverError(FacecapError, RuntimeError):
    """A numerical solve failed even though the input passed validation."""


class FacecapWarning(UserWarning):
    """Something was repaired or ignored; the result is usable but worth a look."""
