"""A mesh's colour texture in USD: a UsdPreviewSurface reading the image beside the file through ``primvars:st``."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from ..structures import Mesh
from .image_file import write_image

__all__ = ["bind_colour_texture", "texture_file_beside", "write_texture_beside"]

_LOOKS = "Looks"


def texture_file_beside(usd_path: str | os.PathLike[str]) -> Path:
    """Where the colour texture of ``NAME.usdc`` goes: ``NAME_color.png`` in its folder (as beside an OBJ)."""
    path = Path(os.fspath(usd_path))
    return path.with_name(f"{path.stem}_color.png")


def write_texture_beside(usd_path: str | os.PathLike[str], mesh: Mesh) -> Path | None:
    """Write ``mesh.texture`` as :func:`texture_file_beside` ``usd_path`` (8 or 16 bits, as held); None when the
    mesh has no texture or no UVs to read it through."""
    if mesh.texture is None or mesh.uvs is None:
        return None
    image = texture_file_beside(usd_path)
    write_image(image, mesh.texture)
    return image


def bind_colour_texture(stage: Any, mesh_path: str, image_name: str) -> None:
    """Bind to the mesh at ``mesh_path`` a material whose diffuse colour is the image ``image_name``.

    The material is the one every USD renderer reads (UsdPreviewSurface, its
    ``diffuseColor`` from a ``UsdUVTexture`` of ``image_name``, sRGB, wrapping
    like OBJ and glTF, sampled at the mesh's ``primvars:st``), placed under
    ``<parent of the mesh>/Looks/Skin``. ``image_name`` is relative to the
    layer's own folder (``./NAME_color.png``), so the file and its image move
    together.

    Parameters
    ----------
    stage : pxr.Usd.Stage
        The stage being authored.
    mesh_path : str
        Path of a ``UsdGeom.Mesh`` with a ``primvars:st``.
    image_name : str
        The image's file name, in the layer's folder.
    """
    from pxr import Sdf, UsdShade

    mesh = stage.GetPrimAtPath(mesh_path)
    looks = mesh.GetPath().GetParentPath().AppendChild(_LOOKS)
    material = UsdShade.Material.Define(stage, looks.AppendChild("Skin"))
    surface = UsdShade.Shader.Define(stage, material.GetPath().AppendChild("PreviewSurface"))
    surface.CreateIdAttr("UsdPreviewSurface")
    surface.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.6)
    surface.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
    reader = UsdShade.Shader.Define(stage, material.GetPath().AppendChild("TexCoords"))
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
    texture = UsdShade.Shader.Define(stage, material.GetPath().AppendChild("Colour"))
    texture.CreateIdAttr("UsdUVTexture")
    texture.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(f"./{image_name}"))
    texture.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("sRGB")
    texture.CreateInput("wrapS", Sdf.ValueTypeNames.Token).Set("repeat")
    texture.CreateInput("wrapT", Sdf.ValueTypeNames.Token).Set("repeat")
    texture.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(
        reader.ConnectableAPI(), "result")
    rgb = texture.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
    surface.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(rgb)
    material.CreateSurfaceOutput().ConnectToSource(surface.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(mesh).Bind(material)
