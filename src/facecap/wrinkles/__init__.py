"""Expression wrinkles from video (Bickel et al. 2007, section 5).

- :class:`PaintClassifier`, :func:`train_paint_classifier`, :func:`classify_paint`,
  :func:`clean_paint_labels`, :func:`separate_paint_colors`, :func:`paint_features`,
  :func:`mask_from_color_picks` (``wrinkle_masks.py``): which pixels wear which paint (section 5.1).
- :class:`WrinkleSpline`, :func:`fit_wrinkle_spline`, :func:`darkness_weights`,
  :func:`control_points_for_length` (``wrinkle_splines.py``): a patch's valley as the
  weighted uniform cubic B-spline of eq. 5 along its principal axis.
- :func:`track_wrinkles`, :class:`WrinkleTracker`, :class:`TrackedWrinkle`,
  :class:`WrinkleTrackingWarning` (``track_wrinkles.py``): one camera's footage to
  valley splines per frame, each wrinkle keeping its identity (section 5.1).
- :func:`cross_section` and :func:`wedge_intensity` (``cross_section.py``): the
  valley model ``S(w, d, p)`` and its sky-lit intensity (eq. 6, 2.5D wedge, closed
  form on tabulated horizons); :func:`profile_sky_visibility`, the brute-force
  eq. 6 on any sampled profile.
- :func:`fit_cross_sections` (``fit_cross_sections.py``): depth and width along a
  valley spline from one image, the ratio fit of eq. 7 by batched Gauss-Newton.
- :class:`DiscreteShell`, :func:`minimize_shell` (``discrete_shell.py``): the nonlinear
  discrete shell of eq. 8 and its damped Gauss-Newton minimiser.
- :class:`SurfaceWrinkle`, :func:`wrinkles_on_surface`, :func:`merge_camera_wrinkles`,
  :func:`anchor_curves`, :func:`identity_parts`, :func:`names_wrinkle` (``surface_wrinkles.py``): valley splines cast onto the animated face, the cameras merged (5.3).
- :func:`synthesize_wrinkles`, :class:`WrinkleSynthesis`, :func:`smoothed_normals`,
  :func:`wrinkle_depth_scale` (``synthesize_wrinkles.py``): valleys imposed and bulges by the
  shell, region by region (5.3); the depth factor its ``depth_scale`` gives each wrinkle.
- :class:`WrinkleFrameStage`, :func:`large_scale_in_mocap`, :func:`result_frame_at`, :func:`first_frame_anchors`,
  :func:`check_cameras_see_the_face`, :func:`check_paint_on_face` (``wrinkle_frame_stage.py``): one video
  frame of the layer, and the checks before a run; the whole take (``facecap wrinkles``) is
  :func:`facecap.pipelines.capture_wrinkles`, on the frame runner.
- :class:`WrinkleEdits`, :func:`read_wrinkle_edits`, :class:`DepthEdit`, :class:`DrawnWrinkle`,
  :func:`svg_path_points` (``wrinkle_edits.py``): depth edits per wrinkle and frame range, wrinkles drawn
  by hand (6.2).
- :func:`remove_wrinkles`, :func:`remove_wrinkles_arrays`, :class:`WrinkleRemoval`
  (``remove_wrinkles.py``): the wrinkles a neutral scan already has, removed by
  multi-scale smoothing with its fine details kept (section 5.4).
"""

from __future__ import annotations

from .wrinkle_masks import (
    PaintClassifier,
    classify_paint,
    clean_paint_labels,
    mask_from_color_picks,
    paint_features,
    separate_paint_colors,
    train_paint_classifier,
)
from .wrinkle_splines import WrinkleSpline, control_points_for_length, darkness_weights, fit_wrinkle_spline
from .track_wrinkles import TrackedWrinkle, WrinkleTracker, WrinkleTrackingWarning, track_wrinkles
from .cross_section import cross_section, profile_sky_visibility, wedge_intensity
from .fit_cross_sections import (
    CrossSections,
    CrossSectionSamples,
    ProfileFit,
    fit_cross_sections,
    fit_profiles,
    sample_cross_sections,
)
from .remove_wrinkles import (
    DEFAULT_DETAIL_SCALE_MM,
    DEFAULT_LARGE_SCALE_MM,
    DEFAULT_SMOOTHING_STEPS,
    WrinkleRemoval,
    remove_wrinkles,
    remove_wrinkles_arrays,
)
from .discrete_shell import DiscreteShell, ShellMinimum, minimize_shell
from .surface_wrinkles import (
    SurfaceWrinkle,
    anchor_curves,
    identity_parts,
    merge_camera_wrinkles,
    names_wrinkle,
    wrinkles_on_surface,
)
from .synthesize_wrinkles import WrinkleSynthesis, smoothed_normals, synthesize_wrinkles, wrinkle_depth_scale
from .wrinkle_frame_stage import (
    WrinkleFrameStage,
    check_cameras_see_the_face,
    check_paint_on_face,
    first_frame_anchors,
    large_scale_in_mocap,
    result_frame_at,
)
from .wrinkle_edits import DepthEdit, DrawnWrinkle, WrinkleEdits, read_wrinkle_edits, svg_path_points

__all__ = [
    "PaintClassifier",
    "train_paint_classifier",
    "classify_paint",
    "clean_paint_labels",
    "separate_paint_colors",
    "paint_features",
    "mask_from_color_picks",
    "WrinkleSpline",
    "fit_wrinkle_spline",
    "darkness_weights",
    "control_points_for_length",
    "track_wrinkles",
    "WrinkleTracker",
    "TrackedWrinkle",
    "WrinkleTrackingWarning",
    "cross_section",
    "wedge_intensity",
    "profile_sky_visibility",
    "fit_cross_sections",
    "fit_profiles",
    "sample_cross_sections",
    "CrossSections",
    "CrossSectionSamples",
    "ProfileFit",
    "DiscreteShell",
    "ShellMinimum",
    "minimize_shell",
    "SurfaceWrinkle",
    "wrinkles_on_surface",
    "merge_camera_wrinkles",
    "anchor_curves",
    "identity_parts",
    "names_wrinkle",
    "synthesize_wrinkles",
    "WrinkleSynthesis",
    "smoothed_normals",
    "wrinkle_depth_scale",
    "WrinkleFrameStage",
    "large_scale_in_mocap",
    "result_frame_at",
    "remove_wrinkles",
    "remove_wrinkles_arrays",
    "WrinkleRemoval",
    "DEFAULT_DETAIL_SCALE_MM",
    "DEFAULT_LARGE_SCALE_MM",
    "DEFAULT_SMOOTHING_STEPS",
    "first_frame_anchors",
    "check_cameras_see_the_face",
    "check_paint_on_face",
    "WrinkleEdits",
    "read_wrinkle_edits",
    "DepthEdit",
    "DrawnWrinkle",
    "svg_path_points",
]
