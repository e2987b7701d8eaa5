"""What a facecap warning means and what to do about it, for the run's report and its reader.

Warnings are written for the log, in a line: what happened. A capture TD reading ``report.html``
also wants to know whether it matters and what to change. :func:`explain_warning` finds the
warning's kind by the words it is written with (the numbers and names in it vary) and gives both;
a warning it does not know gets a general explanation, so a new warning never goes unexplained.
"""

from __future__ import annotations

import re
from typing import NamedTuple

__all__ = ["WarningAdvice", "explain_warning"]


class WarningAdvice(NamedTuple):
    """What a warning means and what to do.

    Attributes
    ----------
    meaning : str
        What the warning says about the run, in a sentence or two.
    action : str
        What the user can do (or why nothing is needed).
    known : bool
        False where the warning was not recognised and the advice is the general one.
    """

    meaning: str
    action: str
    known: bool = True


# (pattern, meaning, action), first match wins: the more specific patterns come first.
_CATALOGUE: tuple[tuple[str, str, str], ...] = (
    # markers and the map
    (r"not in the (correspondence|marker) map",
     "These markers of the take have no place on the scan in the marker map, so they do not drive the face.",
     "Nothing, if they are head-band or other reference markers (they can still serve to find the head's "
     "motion). If a face marker is listed, add it to the map or check that its label matches the take's."),
    (r"duplicate marker label",
     "The take holds two or more markers with the same label; facecap renamed the repeats, so the map may "
     "drive the wrong one.",
     "Fix the labels in the capture software (or the take's export) and check the map uses the intended markers."),
    (r"land off the model",
     "These markers sit where the muscle model has no flesh (ears, scalp, neck, eyes, inner lips), so the "
     "muscle solve leaves them out.",
     "Nothing if the markers really are there. Otherwise check the marker map: a face marker mapped off the face "
     "is a mapping error."),
    (r"rest frame does not fit the scan rigidly",
     "The take's rest frame differs from the scan by more than a rigid move (another person's markers, a "
     "different expression, or errors in the map), so the take was carried onto the scan by the warp, as "
     "facecap animate does.",
     "Expected with a generic map or another person's take. With a map made for this scan and take, look at the "
     "markers with the largest leave-one-out warp residuals and at the rest frame."),
    # the rest pose
    (r"rest(ing)? (frame|pose|expression|face).*(expression|scan)|expression.*rest (frame|pose)",
     "The take's rest frame does not show the scan's expression: after the best rigid fit its markers remain "
     "farther from their places on the scan than the take's noise explains. facecap says here how it treated "
     "the difference (kept as motion, or warped away as marker placement error).",
     "Look at the rest-pose figures and the per-marker table: a few markers far off point to placement error in "
     "the map; a smooth pattern (mouth corners, brows) to an expression. If the actor has a neutral moment, give "
     "it as the neutral reference; if the map was placed by hand on this scan, the mode can be set explicitly "
     "(see facecap animate --help)."),
    (r"markers sit .* (further from|closer to) the skin than --marker-offset",
     "Fitted to the scan, the rest frame's markers sit off the skin by a different height than the marker offset "
     "says, all together (a shared shift along the skin's normals, not an expression): the markers are flatter "
     "or taller than assumed, or sit on stalks.",
     "Give the height the message names with --marker-offset, so that each frame's motion is carried with the "
     "right offset; at rest the warp absorbs the difference either way."),
    # head motion
    (r"head pose rests on .* may move with the face",
     "The markers the head's pose was taken from include one that may move with the face (its label names the "
     "chin, jaw, lips or mouth, or it moved in the take), so part of its motion can be read as head motion (a jaw "
     "opening as a nod).",
     "Nothing if the face looks right in the review. Otherwise name skull or head-band markers with "
     "--stabilize LABEL,LABEL,... or use --stabilize consensus."),
    (r"no head motion beyond what the expressions move",
     "No set of markers moved rigidly by more than the expressions move the most rigid ones, so facecap found "
     "no head motion to remove and left the take as it was captured.",
     "Nothing if the head was still (a head rest, a seated actor). If the head did move, name the stable "
     "markers (a head band, forehead, temples) to force the stabilisation."),
    (r"stable markers .* missing at rest",
     "Some markers chosen as the head's rigid set are not seen at the rest frame, so they cannot help find "
     "the head's pose.",
     "Choose a rest frame where they are visible, or name other stable markers."),
    (r"fewer than 3 stable markers",
     "In these frames fewer than three of the head's rigid markers were seen, too few to find the head's pose; "
     "the frames are left empty (NaN) in the stabilised take.",
     "Add stable markers that stay in view (a head band), or fill the gaps in the capture software before "
     "solving."),
    (r"\b(stable|rigid)\b.*\b(jaw|lips?|mouth)\b|\b(jaw|lips?|mouth)\b.*\b(stable|rigid)\b",
     "The markers used as the head's rigid set include one on the jaw or lips, which move with the expressions; "
     "the head motion found then absorbs part of the expression (a jaw opening read as a nod).",
     "Name stable markers on the forehead, temples or nose bridge, or on a head band, for the head motion "
     "(see facecap animate --help for --stabilize)."),
    # conditioning
    (r"not visible within .* of rest_frame",
     "These markers are not seen near the rest frame, so the filter cannot compare them with their rest "
     "position and smooths them in time only.",
     "Choose a rest frame where every marker is seen, or fill the gaps in the capture software."),
    # units
    (r"which no length unit explains",
     "The scan and the take differ in size by a factor that no change of unit explains: the scan may be of "
     "another person, scaled, or the take's unit may be wrong.",
     "Check the units given for the scan and the take (facecap info shows what each file holds), and that "
     "both are of the same person."),
    (r": read as (millimetres|centimetres|metres|inches|decimetres)",
     "The scan's size did not match the take's in the unit it was read in, so facecap read it in the unit that "
     "makes the two match (the message names it and the sizes it compared).",
     "Nothing if that unit is right; otherwise give the scan's and the take's units explicitly."),
    # the scan and the solver
    (r"piece\(s\) of the scan carry no marker",
     "Parts of the scan (eyes, teeth, separate shells) have no marker on them; they follow the nearest marked "
     "surface ('carry') or stay still ('rigid').",
     "Usually right for eyes and teeth. If a part of the face itself is listed, the scan is split there: check it "
     "with facecap info, or add markers to that part."),
    (r"pypardiso|PARDISO.*not available",
     "The fast sparse solver (MKL PARDISO, package pypardiso) is not installed, so SciPy's slower solver was "
     "used; the result is the same, only slower and larger in memory.",
     "Install pypardiso (pip install pypardiso) on x86-64 Linux or Windows."),
    (r"not positive definite",
     "In some frames the simulated flesh reached an unstable equilibrium or inverted elements; the solver's "
     "sensitivities are approximate there and those frames may be less accurate.",
     "Look at the frames flagged in the report; a cleaner or finer muscle model usually helps."),
    (r"recomputing a damaged chunk",
     "A saved piece of an earlier, interrupted run was unreadable and was computed again.",
     "Nothing: the result is complete."),
    (r"triangles are wound inward",
     "The scan's triangles face inward (flipped normals); facecap turned them round.",
     "Nothing for facecap; other tools may show the original scan inside out."),
    # scan planning and blend shapes
    (r"no further frame lowers the error",
     "Adding scans stopped lowering the plan's error before the tolerance was reached: the take holds motion "
     "that no combination of scanned expressions reproduces well.",
     "Accept the plan's error, raise the tolerance, or check the take for noise or marker swaps in the frames "
     "with the largest residuals."),
    (r"no correspondence\.npz",
     "The result lacks the map from the face back to the capture's frame, so facecap wrinkles cannot use it.",
     "Make sure at least four markers are seen at the rest frame and every frame's head pose is found."),
    (r"exact rig needs .* blend shapes",
     "The exact blend-shape rig would be too large for USD, so the export holds its first principal components "
     "instead (their error is in performance.json).",
     "Use the exact rig in rig/ where precision matters, or ask for the exact form (--usd-shapes exact)."),
    # file reading
    (r"texture coordinates; the UVs are dropped|only some meshes have texture coordinates",
     "The scan has texture coordinates on only part of it, so facecap dropped them; the result has no UVs.",
     "Re-export the scan with UVs on every face if the result needs a texture."),
    (r"vertices have colours",
     "Only some of the scan's vertices carry a colour, so facecap dropped the colours.",
     "Re-export the scan with a colour on every vertex if the colours are needed."),
    (r"cannot be stored in a C3D header",
     "The take's first frame number does not fit a C3D header, so the written take starts at frame 0.",
     "Keep the original frame numbers from the source take where they matter (timecode, editorial)."),
    # wrinkles
    (r"was not found; it is left out until it reappears",
     "A painted wrinkle was not found in this video frame (hidden, out of focus or too faint), so it is left "
     "out until it is seen again.",
     "Nothing if the wrinkle really disappears. Otherwise check the footage at that frame (lighting, "
     "occlusion) or draw the wrinkle there with an edit file."),
    (r"reaches the image border",
     "A tracked wrinkle touches the edge of the image, so its curve covers only the part in view.",
     "Frame the cameras so the face stays inside the image, or accept the shortened wrinkle."),
    (r"curve misses the face",
     "A drawn wrinkle's curve does not land on the face seen from this camera at this frame, so it is left out "
     "there.",
     "Redraw the wrinkle inside the face in that camera's image."),
    (r"land on the face; its calibration",
     "Few of the wrinkles this camera tracks land on the face: its calibration may not match the footage.",
     "Check the camera's calibration file (intrinsics, pose, units) against the footage."),
    (r"hold no video frame, so the edit does nothing",
     "An edit was given for mocap frames that no video frame falls on, so it has no effect.",
     "Move the edit to mocap frames covered by the footage."),
)

_COMPILED = tuple((re.compile(pattern, re.IGNORECASE), meaning, action) for pattern, meaning, action in _CATALOGUE)

_GENERAL = WarningAdvice(
    meaning="facecap finished the run but noticed something that may affect the result; the message says what.",
    action="Check the part of the result the message names (the review page shows every frame); if it matters, "
           "fix the input and run again.",
    known=False,
)


def explain_warning(message: str) -> WarningAdvice:
    """What a warning of a facecap run means and what to do, for the run's report.

    Parameters
    ----------
    message : str
        The warning as ``report.json`` records it (its numbers, file and marker names may vary).

    Returns
    -------
    WarningAdvice
        ``meaning``, ``action``, and ``known`` (False: the warning was not recognised and the
        advice is general).

    Examples
    --------
    >>> advice = explain_warning("4 take marker(s) are not in the marker map, so they do not drive the face: ['HB0']")
    >>> advice.known, advice.meaning.startswith("These markers of the take have no place on the scan")
    (True, True)
    >>> explain_warning("something new").known
    False
    """
    text = str(message)
    for pattern, meaning, action in _COMPILED:
        if pattern.search(text):
            return WarningAdvice(meaning, action)
    return _GENERAL
