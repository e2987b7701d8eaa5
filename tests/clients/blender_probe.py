"""Import files into Blender and dump the vertices it evaluates at given frames.

Run with the Blender environment's interpreter (``bpy`` as a module, see
``blender_env.py``), never with facecap's: it imports only ``bpy`` and numpy::

    python blender_probe.py jobs.json

``jobs.json`` holds ``{"jobs": [job, ...]}``; each job is imported into an
empty scene of its own (factory settings, so nothing carries over), in one
Blender process for all of them (bpy's start-up is paid once). A job:

- ``name``: a label; ``out``: the ``.npz`` to write;
- ``importer``: ``'usd'``, ``'obj'``, ``'gltf'`` or ``'alembic'``, and
  ``path``, the file; ``options``: keyword arguments of the import operator
  (``bpy.ops.wm.usd_import``, ``wm.obj_import``, ``import_scene.gltf``,
  ``wm.alembic_import``);
- ``fps``, ``fps_base``: the scene's frame rate (``fps / fps_base`` Hz), set
  *before* the import (the glTF importer converts seconds to frames with it);
- ``mesh_cache`` (optional): settings of a ``MESH_CACHE`` modifier added to
  the imported mesh (``filepath``, ``cache_format``, axes, frame settings:
  any attribute of ``bpy.types.MeshCacheModifier``);
- ``shape_key_range`` (optional): ``[low, high]`` set as every shape key's
  slider range after the import (Blender clamps a shape key's value to it);
- ``mesh_object`` (optional): the name of the mesh object to evaluate when
  the import makes several (default: the only one);
- ``track_objects`` (optional): names of objects whose evaluated world
  matrices are dumped too (``tracked_<f>``, ``(K, 4, 4)``);
- ``frames``: the scene frames to evaluate.

For each frame the scene is set (``scene.frame_set``), the depsgraph is
evaluated, and the evaluated object's mesh (``evaluated_get(depsgraph)
.to_mesh()``: modifiers, shape keys, caches and constraints applied) is taken
to world space with the evaluated ``matrix_world``. The ``.npz`` holds
``frame_<f>`` ``(v, 3)`` float64 world positions in Blender units (metres at
the default unit scale), ``frames``, ``rest_local`` (the mesh data's own
vertices, object space, before any modifier or shape key), ``polygon_sizes``,
``polygon_vertices``, ``corner_uvs`` (the first UV layer, one per polygon
corner, when there is one), and a JSON ``info`` (objects, modifiers, constraints,
shape keys and their slider ranges as imported and as evaluated, the scene's
frame range, timings), or
only ``error`` (the traceback) when the job failed. Failures are recorded, not
raised, so one bad import does not hide the others' results.
"""

from __future__ import annotations

import json
import sys
import time
import traceback
from pathlib import Path

import bpy
import numpy as np

_IMPORTERS = {
    "usd": lambda: bpy.ops.wm.usd_import,
    "obj": lambda: bpy.ops.wm.obj_import,
    "gltf": lambda: bpy.ops.import_scene.gltf,
    "alembic": lambda: bpy.ops.wm.alembic_import,
}


def _mesh_objects() -> list:
    return [ob for ob in bpy.context.scene.objects if ob.type == "MESH"]


def _world_vertices(ob, depsgraph) -> np.ndarray:
    evaluated = ob.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
        mesh.vertices.foreach_get("co", co)
    finally:
        evaluated.to_mesh_clear()
    M = np.array(evaluated.matrix_world, dtype=np.float64)
    return co.reshape(-1, 3).astype(np.float64) @ M[:3, :3].T + M[:3, 3]


def _describe(ob) -> dict:
    keys = ob.data.shape_keys
    return {
        "name": ob.name,
        "parent": ob.parent.name if ob.parent else None,
        "scale": list(ob.matrix_world.to_scale()),
        "modifiers": [m.type for m in ob.modifiers],
        "constraints": [c.type for c in ob.constraints],
        "shape_keys": [
            {"name": k.name, "value": k.value, "slider_min": k.slider_min, "slider_max": k.slider_max}
            for k in keys.key_blocks
        ] if keys else [],
        "shape_keys_animated": bool(keys and keys.animation_data and keys.animation_data.action),
        "n_vertices": len(ob.data.vertices),
        "n_polygons": len(ob.data.polygons),
        "n_loops": len(ob.data.loops),
        "uv_layers": [uv.name for uv in ob.data.uv_layers],
    }


def run_job(job: dict) -> dict:
    """Import one job's file into an empty scene and return the arrays to save."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = int(job["fps"])
    scene.render.fps_base = float(job.get("fps_base", 1.0))
    started = time.perf_counter()
    result = _IMPORTERS[job["importer"]]()(filepath=job["path"], **job.get("options", {}))
    import_seconds = time.perf_counter() - started
    if "FINISHED" not in result:
        raise RuntimeError(f"the {job['importer']} importer returned {result}")
    objects = _mesh_objects()
    if job.get("mesh_object"):
        ob = scene.objects[job["mesh_object"]]
    elif len(objects) == 1:
        ob = objects[0]
    else:
        raise RuntimeError(f"expected one mesh object, the import made {[o.name for o in objects]}")
    tracked = [scene.objects[name] for name in job.get("track_objects", [])]
    shape_key_sliders = _describe(ob)["shape_keys"]  # as the importer left them
    if job.get("shape_key_range") and ob.data.shape_keys:
        low, high = job["shape_key_range"]
        for key in ob.data.shape_keys.key_blocks:
            key.slider_min, key.slider_max = float(low), float(high)
    if job.get("mesh_cache"):
        modifier = ob.modifiers.new("facecap cache", "MESH_CACHE")
        for key, value in job["mesh_cache"].items():
            setattr(modifier, key, value)
    arrays: dict[str, np.ndarray] = {}
    for frame in job["frames"]:
        scene.frame_set(int(frame))
        depsgraph = bpy.context.evaluated_depsgraph_get()
        arrays[f"frame_{int(frame)}"] = _world_vertices(ob, depsgraph)
        if tracked:
            arrays[f"tracked_{int(frame)}"] = np.array(
                [np.array(o.evaluated_get(depsgraph).matrix_world, dtype=np.float64) for o in tracked]
            )
    rest = np.empty(len(ob.data.vertices) * 3, dtype=np.float32)
    ob.data.vertices.foreach_get("co", rest)
    sizes = np.empty(len(ob.data.polygons), dtype=np.int32)
    ob.data.polygons.foreach_get("loop_total", sizes)
    corners = np.empty(len(ob.data.loops), dtype=np.int32)
    ob.data.loops.foreach_get("vertex_index", corners)
    info = {
        "blender": bpy.app.version_string,
        "object": _describe(ob),
        "imported_shape_keys": shape_key_sliders,
        "other_objects": [o.name for o in scene.objects if o is not ob],
        "scene_frame_start": scene.frame_start,
        "scene_frame_end": scene.frame_end,
        "scene_fps": scene.render.fps / scene.render.fps_base,
        "import_seconds": import_seconds,
    }
    if ob.data.uv_layers:
        uv = np.empty(len(ob.data.loops) * 2, dtype=np.float32)
        ob.data.uv_layers[0].data.foreach_get("uv", uv)
        arrays["corner_uvs"] = uv.reshape(-1, 2).astype(np.float64)
    arrays.update(
        frames=np.asarray(job["frames"], dtype=np.int64),
        rest_local=rest.reshape(-1, 3).astype(np.float64),
        polygon_sizes=sizes.astype(np.int64),
        polygon_vertices=corners.astype(np.int64),
        info=np.array(json.dumps(info)),
    )
    return arrays


def main(jobs_file: str) -> None:
    jobs = json.loads(Path(jobs_file).read_text())["jobs"]
    for job in jobs:
        try:
            arrays = run_job(job)
        except Exception:  # recorded for the test to report, see the module docstring
            arrays = {"error": np.array(traceback.format_exc())}
        np.savez(job["out"], **arrays)
        print(f"facecap probe: {job['name']}: {'failed' if 'error' in arrays else 'ok'}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1])
