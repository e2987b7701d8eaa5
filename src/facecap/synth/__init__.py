"""Synthetic ground truth: the bundled ICT face sample and generated capture takes.

In the order a user meets them:

- (the bundled ICT-FaceKit face and AnimFace take it builds on are read by
  :func:`facecap.io.load_ict_sample`)
- :func:`generate_performance` (``generate_performance.py``): a take with
  dense ground truth, as a :class:`SyntheticCase`; :func:`named_curves` picks
  one of the :data:`CURVE_GENERATORS`, :data:`HEAD_PIVOTS_MM` are the head
  pivots (the normals it lifts markers along: :func:`facecap.mesh.vertex_normals`);
  :func:`rotational_jaw_correction`, :func:`fit_jaw_screw`, :class:`JawScrew`,
  :data:`ICT_JAW_SCREW`, :data:`JAW_MODES` (``rotational_jaw.py``) make its ``jaw='rotational'``
  (the jaw opening along its arc instead of the blendshape's straight lines);
  :func:`random_rest_expression`, :data:`RESTING_SHAPES` (``rest_expression.py``) its
  ``rest_expression`` (a take whose resting face is not the scan's).
- The weight curves it can drive the face with:
  :func:`smooth_expression_curves`, :data:`EXPRESSION_PRESETS`
  (``expression_curves.py``), smooth expressions;
  :func:`speech_expression_curves`, :data:`VOWEL_VISEMES`,
  :data:`CONSONANT_VISEMES` (``speech_curves.py``), speech-like visemes;
  :func:`real_motion_curves`, :func:`load_real_curve_fit`, :class:`RealCurveFit`,
  :data:`REAL_CURVE_NAMES` (``real_motion_curves.py``), weights fitted to the
  bundled AnimFace take. They ease with :func:`smoothstep` (``smoothstep.py``), the quintic
  smoothstep, and blink with :func:`blink_curve` (``blink_curve.py``).
- :func:`choose_marker_vertices`, :func:`animface_marker_map`,
  :func:`boundary_vertices` (``marker_layout.py``): where the virtual markers go.
- :func:`scan_expression` (``scan_expression.py``): an expression "scanned" the
  way a range scanner would, as a :class:`ScannedExpression`.
- :func:`skin_albedo`, :class:`SkinRegions`, :data:`BASE_SKIN_TONE`
  (``skin_albedo.py``): the skin's linear reflectance as a solid texture of
  the material point; :func:`bake_skin_albedo`, :class:`SkinTexture`, :func:`textured_neutral`
  (``skin_texture.py``): that albedo, pores included, baked once per identity into the rest
  surface's UV atlas, which generated scans' textures and the textured neutral read;
  :func:`capture_colors` (``capture_colors.py``): what a
  scanner's camera records of it (exposure, shading, noise, sRGB by
  :func:`facecap.cameras.linear_to_srgb`), for ``Mesh.vertex_colors``.
- :func:`write_synthetic_case`, :func:`write_planned_scans`
  (``write_synthetic_case.py``): a case on disk as a user would hold it
  (scan, take, map, truth), as :class:`CaseFiles`; :func:`correspondence_json`, its ``map.json``.
- Footage with ground truth for the wrinkle layer (Bickel et al. 2007, section 5):
  :func:`subdivide_scan`, :class:`SubdividedScan`, :func:`refine_near` (``wrinkle_scan.py``), the
  scan fine enough to hold wrinkles; :func:`place_wrinkles`,
  :func:`add_wrinkles`, :func:`wrinkle_heights`, :func:`wrinkle_profile`, :func:`wrinkle_activation`,
  :class:`WrinkleCurves`, :class:`WrinkledPerformance`, :data:`WRINKLE_KINDS`,
  :data:`INFLUENCE_WIDTHS`, :func:`wrinkle_expression_curves`, :func:`every_wrinkle_at_once`,
  :data:`WRINKLE_EXPRESSIONS` (``wrinkles.py``), the truth wrinkles;
  :func:`paint_wrinkles`, :class:`PaintedSkin`, :data:`PAINT_COLORS`,
  :data:`PAINT_HALF_WIDTH` (``wrinkle_paint.py``); :class:`FootageRenderer`,
  :func:`ambient_occlusion`, :func:`sensor_noise`, :func:`quantize`,
  :data:`SENSOR_DEFAULTS` (``render_footage.py``), the renderer;
  :func:`write_footage_case`, :func:`stage_cameras`, :class:`FootageFiles`,
  :data:`MOCAP_RATE_HZ`, :data:`VIDEO_RATE_HZ`, :func:`write_take_files`, :class:`TakeFiles`
  (``write_footage_case.py``), a case with its footage and truth on disk. The scan's labels
  carried to the fine mesh by :func:`carry_labels` (``wrinkle_scan.py``); lines drawn in the
  frontal plane by :func:`wrinkle_curves_on_surface` (``wrinkles.py``).
- Footage with ground truth for the detail layer (space-time shape from shading, Lo et al.):
  :func:`place_fine_lines`, :func:`skin_texture_heights`, :func:`double_crease_profile`,
  :data:`FINE_LINE_KINDS`, :data:`FINE_LINE_PROFILES`, :data:`SKIN_TEXTURE_RMS_MM` (``fine_lines.py``),
  the fine lines and the skin's static bumps; :func:`skin_albedo_layers`, :class:`SkinLayers`,
  :func:`band_noise` (``skin_albedo.py``), the albedo with moles and its marks apart; :func:`skin_flush`,
  :class:`SkinFlush`, :data:`FLUSH_TINT` (``skin_flush.py``), the cheeks' flush with the smile;
  :func:`studio_lights`, :data:`LIGHTING_STYLES` (``studio_lights.py``), the stage's lights;
  :func:`shade_skin`, :func:`skin_radiance`, :func:`subsurface_blur`, :func:`region_reflectance`,
  :class:`Shading`, :data:`REGION_REFLECTANCE`, :data:`APPEARANCES` (``shade_skin.py``), Phong and the
  independent microfacet skin; :func:`draw_markers` (``draw_markers.py``), the markers in the images;
  :func:`write_detail_case`, :class:`DetailFiles`, :data:`DETAIL_EDGE_MM`, :data:`DETAIL_VIDEO_EVERY`,
  :data:`MARKER_RADIUS_MM`, :data:`MARKER_ALBEDO` (``write_detail_case.py``), the case on disk.
- :func:`render_mirror_sphere`, :data:`MIRROR_SPHERE_DEFAULTS` (``mirror_sphere.py``): a chrome
  sphere reflecting a light, as calibrated cameras see it (``facecap calibrate-light``'s footage).
"""

from __future__ import annotations

from .blink_curve import blink_curve
from .expression_curves import EXPRESSION_PRESETS, smooth_expression_curves
from .generate_performance import (
    CURVE_GENERATORS,
    HEAD_PIVOTS_MM,
    SyntheticCase,
    generate_performance,
    named_curves,
    random_identity,
    RANDOM_IDENTITY_SD,
)
from .capture_colors import capture_colors
from .marker_layout import animface_marker_map, boundary_vertices, choose_marker_vertices
from .real_motion_curves import REAL_CURVE_NAMES, RealCurveFit, load_real_curve_fit, real_motion_curves
from .rest_expression import RESTING_SHAPES, as_rest_weights, random_rest_expression
from .rotational_jaw import ICT_JAW_SCREW, JAW_MODES, JawScrew, fit_jaw_screw, rotational_jaw_correction
from .scan_expression import DEFAULT_SCAN_TEXEL_MM, ScannedExpression, scan_expression
from .skin_albedo import BASE_SKIN_TONE, SkinLayers, SkinRegions, band_noise, skin_albedo, skin_albedo_layers
from .skin_texture import DEFAULT_ALBEDO_TEXELS, SkinTexture, bake_skin_albedo, textured_neutral
from .smoothstep import smoothstep
from .speech_curves import CONSONANT_VISEMES, VOWEL_VISEMES, speech_expression_curves
from .write_synthetic_case import CaseFiles, correspondence_json, write_planned_scans, write_synthetic_case
from .wrinkle_scan import SubdividedScan, carry_labels, refine_near, subdivide_scan
from .wrinkles import (INFLUENCE_WIDTHS, WRINKLE_EXPRESSIONS, WRINKLE_KINDS, WrinkleCurves, WrinkledPerformance,
                       add_wrinkles, every_wrinkle_at_once, place_wrinkles, wrinkle_activation,
                       wrinkle_curves_on_surface, wrinkle_expression_curves, wrinkle_heights, wrinkle_profile)
from .wrinkle_paint import PAINT_COLORS, PAINT_HALF_WIDTH, PaintedSkin, paint_wrinkles
from .render_footage import SENSOR_DEFAULTS, FootageRenderer, ambient_occlusion, quantize, sensor_noise
from .mirror_sphere import MIRROR_SPHERE_DEFAULTS, render_mirror_sphere
from .write_footage_case import (MOCAP_RATE_HZ, VIDEO_RATE_HZ, FootageFiles, TakeFiles, stage_cameras,
                                 write_footage_case, write_take_files)
from .fine_lines import (FINE_LINE_KINDS, FINE_LINE_PROFILES, SKIN_TEXTURE_RMS_MM, double_crease_profile,
                         place_fine_lines, skin_texture_heights)
from .shade_skin import (APPEARANCES, REGION_REFLECTANCE, Shading, region_reflectance, shade_skin, skin_radiance,
                         subsurface_blur)
from .skin_flush import FLUSH_TINT, SkinFlush, skin_flush
from .studio_lights import LIGHTING_STYLES, studio_lights
from .draw_markers import draw_markers
from .write_detail_case import (DETAIL_EDGE_MM, DETAIL_VIDEO_EVERY, MARKER_ALBEDO, MARKER_RADIUS_MM, DetailFiles,
                                write_detail_case)

__all__ = [
    "SkinTexture",
    "DEFAULT_ALBEDO_TEXELS",
    "DEFAULT_SCAN_TEXEL_MM",
    "bake_skin_albedo",
    "textured_neutral",
    "render_mirror_sphere",
    "MIRROR_SPHERE_DEFAULTS",
    "random_identity",
    "RANDOM_IDENTITY_SD",
    "generate_performance",
    "SyntheticCase",
    "named_curves",
    "CURVE_GENERATORS",
    "HEAD_PIVOTS_MM",
    "random_rest_expression",
    "RESTING_SHAPES",
    "as_rest_weights",
    "rotational_jaw_correction",
    "fit_jaw_screw",
    "JawScrew",
    "ICT_JAW_SCREW",
    "JAW_MODES",
    "smooth_expression_curves",
    "smoothstep",
    "blink_curve",
    "EXPRESSION_PRESETS",
    "speech_expression_curves",
    "VOWEL_VISEMES",
    "CONSONANT_VISEMES",
    "real_motion_curves",
    "load_real_curve_fit",
    "RealCurveFit",
    "REAL_CURVE_NAMES",
    "choose_marker_vertices",
    "animface_marker_map",
    "boundary_vertices",
    "scan_expression",
    "ScannedExpression",
    "skin_albedo",
    "SkinRegions",
    "BASE_SKIN_TONE",
    "capture_colors",
    "write_synthetic_case",
    "write_planned_scans",
    "correspondence_json",
    "CaseFiles",
    "subdivide_scan",
    "SubdividedScan",
    "refine_near",
    "carry_labels",
    "place_wrinkles",
    "add_wrinkles",
    "wrinkle_profile",
    "wrinkle_activation",
    "wrinkle_heights",
    "WrinkleCurves",
    "WrinkledPerformance",
    "WRINKLE_KINDS",
    "INFLUENCE_WIDTHS",
    "wrinkle_expression_curves",
    "every_wrinkle_at_once",
    "WRINKLE_EXPRESSIONS",
    "paint_wrinkles",
    "PaintedSkin",
    "PAINT_COLORS",
    "PAINT_HALF_WIDTH",
    "FootageRenderer",
    "ambient_occlusion",
    "sensor_noise",
    "quantize",
    "SENSOR_DEFAULTS",
    "write_footage_case",
    "stage_cameras",
    "FootageFiles",
    "MOCAP_RATE_HZ",
    "VIDEO_RATE_HZ",
    "place_fine_lines",
    "skin_texture_heights",
    "double_crease_profile",
    "FINE_LINE_KINDS",
    "shade_skin",
    "skin_radiance",
    "region_reflectance",
    "REGION_REFLECTANCE",
    "APPEARANCES",
    "skin_flush",
    "SkinFlush",
    "studio_lights",
    "draw_markers",
    "write_detail_case",
    "DetailFiles",
    "DETAIL_EDGE_MM",
    "DETAIL_VIDEO_EVERY",
    "MARKER_RADIUS_MM",
    "MARKER_ALBEDO",
    "FINE_LINE_PROFILES",
    "SKIN_TEXTURE_RMS_MM",
    "Shading",
    "subsurface_blur",
    "FLUSH_TINT",
    "LIGHTING_STYLES",
    "skin_albedo_layers",
    "SkinLayers",
    "band_noise",
    "wrinkle_curves_on_surface",
    "write_take_files",
    "TakeFiles",
]
