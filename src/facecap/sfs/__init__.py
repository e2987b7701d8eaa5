"""Fine detail from video by space-time shape from shading (Lo et al.): the solver side.

Arrays in, arrays out; the job that reads a result and footage and writes the detail
result is :func:`facecap.pipelines.capture_detail` (``facecap detail``). ``docs/detail.md``
has the method step by step and the decisions.

- :func:`phong_shading`, :class:`PhongShading` (``phong_shading.py``): eq. 3 with every light,
  falloff, shadows and ambient, and its derivative along the normal.
- :func:`vertex_gradient`, :class:`VertexGradient` (``vertex_gradient.py``): heights to normals.
- :func:`solve_heights`, :func:`shade_frame`, :class:`ShadedFrame`, :class:`HeightWeights`,
  :class:`HeightSolve`, :data:`TEMPORAL_REACH` (``solve_heights.py``): the space-time solve (eqs. 6-8).
- :func:`estimate_reflectance`, :class:`Reflectance`, :data:`PHONG_EXPONENTS` (``estimate_reflectance.py``):
  albedo and Phong lobe from the rest frame.
- :class:`SurfaceLowPass` (``surface_low_pass.py``): the slow gain's filter.
- :func:`sample_footage`, :class:`FootageSamples`, :data:`LUMINANCE`, :data:`CLIPPED_LEVEL`
  (``sample_footage.py``): footage onto the skin.
- :func:`select_detail_region` (``select_detail_region.py``): the default region.
- :class:`DetailFrameStage`, :data:`DETAIL_DEFAULTS` (``detail_frame_stage.py``): a window of video
  frames on the frame runner.
"""

from __future__ import annotations

from .detail_frame_stage import DETAIL_DEFAULTS, DetailFrameStage
from .estimate_reflectance import PHONG_EXPONENTS, Reflectance, estimate_reflectance
from .phong_shading import PhongShading, phong_shading
from .sample_footage import CLIPPED_LEVEL, LUMINANCE, FootageSamples, sample_footage
from .select_detail_region import BOUNDARY_RINGS, MIN_LIGHT_SHARE, MIN_VIEW_WEIGHT, select_detail_region
from .solve_heights import TEMPORAL_REACH, HeightSolve, HeightWeights, ShadedFrame, shade_frame, solve_heights
from .surface_low_pass import SurfaceLowPass
from .vertex_gradient import VertexGradient, vertex_gradient

__all__ = [
    "phong_shading", "PhongShading",
    "vertex_gradient", "VertexGradient",
    "solve_heights", "shade_frame", "ShadedFrame", "HeightWeights", "HeightSolve", "TEMPORAL_REACH",
    "estimate_reflectance", "Reflectance", "PHONG_EXPONENTS",
    "SurfaceLowPass",
    "sample_footage", "FootageSamples", "LUMINANCE", "CLIPPED_LEVEL",
    "select_detail_region", "MIN_VIEW_WEIGHT", "MIN_LIGHT_SHARE", "BOUNDARY_RINGS",
    "DetailFrameStage", "DETAIL_DEFAULTS",
]
