"""Fine detail from video by space-time shape from shading (Lo et al.): the solver side.

Arrays in, arrays out; the job that reads a result and footage and writes the detail
result is :func:`facecap.pipelines.capture_detail` (``facecap detail``). ``docs/detail.md``
has the method step by step and the decisions.

- :func:`phong_shading`, :class:`PhongShading` (``phong_shading.py``): eq. 3 with every light,
  falloff, shadows and ambient, and its derivative along the normal.
- :func:`vertex_gradient`, :class:`VertexGradient` (``vertex_gradient.py``): heights to normals.
- :func:`solve_heights`, :func:`shade_frame`, :class:`ShadedFrame`, :class:`HeightWeights`,
  :class:`HeightSolve`, :data:`TEMPORAL_REACH` (``solve_heights.py``): the space-time solve (eqs. 6-8).
- :class:`FrameNormalProduct`, :class:`OneRingPattern`, :func:`compile_blur` (``normal_product.py``): the
  solve's normal-equations product, compiled.
- :func:`estimate_reflectance`, :func:`rest_misfit`, :class:`Reflectance`, :data:`PHONG_EXPONENTS`,
  :data:`REST_MISFIT_LIMIT` (``estimate_reflectance.py``): albedo and Phong lobe from the rest frame, and
  the samples it cannot explain.
- :class:`SurfaceLowPass` (``surface_low_pass.py``): the slow gain's filter.
- :class:`BilateralHeights`, :data:`DEFAULT_BILATERAL_MM` (``bilateral_heights.py``): the paper's optional
  post-filter (4.3).
- :func:`sample_footage`, :func:`luminance`, :class:`FootageSamples`, :data:`LUMINANCE`, :data:`CLIPPED_LEVEL`
  (``sample_footage.py``): footage onto the skin.
- :func:`follow_skin`, :data:`FLOW_LIMIT_PX` (``follow_skin.py``): optical flow against the rest frame, so
  that a sample reads the same skin point in every frame.
- :func:`camera_blur`, :data:`DEFAULT_BLUR_PX` (``camera_blur.py``): the camera's point spread on the skin.
- :func:`select_detail_region`, :func:`locality_order` (``select_detail_region.py``): the default region,
  and the order its samples are solved in.
- :class:`DetailFrameStage`, :data:`DETAIL_DEFAULTS` (``detail_frame_stage.py``): a window of video
  frames on the frame runner.
- :class:`DetailMaps`, :data:`FLAT_NORMAL`, :data:`FLAT_ENCODED` (``detail_maps.py``): the detail's
  displacement and tangent-space normal maps on the scan's UVs.
"""

from __future__ import annotations

from .bilateral_heights import DEFAULT_BILATERAL_MM, BilateralHeights
from .camera_blur import DEFAULT_BLUR_PX, camera_blur
from .detail_frame_stage import DETAIL_DEFAULTS, DetailFrameStage
from .detail_maps import FLAT_ENCODED, FLAT_NORMAL, DetailMaps
from .estimate_reflectance import PHONG_EXPONENTS, REST_MISFIT_LIMIT, Reflectance, estimate_reflectance, rest_misfit
from .normal_product import FrameNormalProduct, OneRingPattern, compile_blur
from .phong_shading import PhongShading, phong_shading
from .follow_skin import FLOW_LIMIT_PX, follow_skin
from .sample_footage import CLIPPED_LEVEL, LUMINANCE, FootageSamples, luminance, sample_footage
from .select_detail_region import (BOUNDARY_RINGS, MIN_LIGHT_SHARE, MIN_VIEW_WEIGHT, locality_order,
                                   select_detail_region)
from .solve_heights import TEMPORAL_REACH, HeightSolve, HeightWeights, ShadedFrame, shade_frame, solve_heights
from .surface_low_pass import SurfaceLowPass
from .vertex_gradient import VertexGradient, vertex_gradient

__all__ = [
    "phong_shading", "PhongShading",
    "vertex_gradient", "VertexGradient",
    "FrameNormalProduct", "OneRingPattern", "compile_blur",
    "solve_heights", "shade_frame", "ShadedFrame", "HeightWeights", "HeightSolve", "TEMPORAL_REACH",
    "estimate_reflectance", "rest_misfit", "Reflectance", "PHONG_EXPONENTS", "REST_MISFIT_LIMIT",
    "SurfaceLowPass",
    "BilateralHeights", "DEFAULT_BILATERAL_MM",
    "sample_footage", "FootageSamples", "luminance", "LUMINANCE", "CLIPPED_LEVEL",
    "follow_skin", "FLOW_LIMIT_PX",
    "select_detail_region", "locality_order", "MIN_VIEW_WEIGHT", "MIN_LIGHT_SHARE", "BOUNDARY_RINGS",
    "DetailFrameStage", "DETAIL_DEFAULTS",
    "DetailMaps", "FLAT_NORMAL", "FLAT_ENCODED",
    "camera_blur", "DEFAULT_BLUR_PX",
]
