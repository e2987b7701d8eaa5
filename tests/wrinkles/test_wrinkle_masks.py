"""The paint classifier (Bickel 2007, 5.1) on drawn stripes of known paint: train_paint_classifier, classify_paint (its table
against the SVMs themselves), mask_from_color_picks; bad masks refused."""

from __future__ import annotations

import numpy as np
import pytest

from facecap.errors import InputError
from facecap.wrinkles import classify_paint, mask_from_color_picks, train_paint_classifier
from wrinkle_stripe_images import two_stripes as _two_stripes


def test_the_table_agrees_with_the_svms_themselves() -> None:
    """The tabulated decision (64^3 bins) labels the pixels as the SVMs do, and matches their decision values."""
    image, labels, _ = _two_stripes()
    classifier = train_paint_classifier(image, labels)
    moved, _, _ = _two_stripes((5.0, 3.0), seed=7)
    direct = classify_paint(classifier, moved, use_table=False)
    table = classify_paint(classifier, moved)
    assert np.mean(direct == table) > 0.999
    rgb = moved.reshape(-1, 3)[::7] / 255.0
    exact, tabulated = classifier.decision(rgb), classifier.table_decision(rgb)
    confident = np.abs(exact) > 0.5
    assert np.all(np.sign(exact[confident]) == np.sign(tabulated[confident]))
    # and the labels are right: the truth of the moved frame, away from its anti-aliased edges
    from scipy.ndimage import maximum_filter, minimum_filter

    _, truth, _ = _two_stripes((5.0, 3.0), seed=7)
    clear = maximum_filter(truth, size=5) == minimum_filter(truth, size=5)
    assert np.mean(table[clear] == truth[clear]) > 0.999


def test_colour_picks_make_the_mask_and_train_as_well() -> None:
    """One picked pixel per paint: the mask covers the stripes' interiors, and its classifier labels a new frame."""
    from scipy.ndimage import maximum_filter, minimum_filter

    image, labels, curves = _two_stripes()
    picks = np.array([curves[0][1000], curves[2][1000]])  # on the blue and the green stripe's centre lines
    mask = mask_from_color_picks(image, picks)
    clear = maximum_filter(labels, size=5) == minimum_filter(labels, size=5)
    assert np.mean(mask[clear] == labels[clear]) > 0.995
    moved, truth, _ = _two_stripes((5.0, 3.0), seed=7)
    found = classify_paint(train_paint_classifier(image, mask), moved)
    clear = maximum_filter(truth, size=5) == minimum_filter(truth, size=5)
    assert np.mean(found[clear] == truth[clear]) > 0.999
    with pytest.raises(InputError, match="outside"):
        mask_from_color_picks(image, [[320, 10]])


def test_a_mask_with_no_pixel_of_a_colour_is_refused() -> None:
    image, labels, _ = _two_stripes()
    skipped = np.where(labels == 1, 3, labels)  # paints 0 (value 1) missing: values 0, 2, 3
    with pytest.raises(InputError, match=r"paint colour 0 \(mask value 1\) has no pixel"):
        train_paint_classifier(image, skipped)
    with pytest.raises(InputError, match="paint colour 1"):
        train_paint_classifier(image, [labels == 1, np.zeros_like(labels, dtype=bool)])
    with pytest.raises(InputError, match="no painted pixel"):
        train_paint_classifier(image, np.zeros_like(labels))
    with pytest.raises(InputError, match="does not match"):
        train_paint_classifier(image, [labels[:-1] == 1])
    with pytest.raises(InputError, match="expected an"):
        train_paint_classifier(image, labels[:, :-1])
