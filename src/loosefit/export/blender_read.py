"""Read an export back in Blender (``bpy``, Blender as a Python module) and say what it sees.

Run as a script, in its own process (``bpy`` carries its own USD libraries, which must
not meet ``usd-core``'s in one process)::

    python blender_read.py FILE [FILE ...] --fps 30 --frames 0 5 9 --out seen.npz [--png view.png]

It imports each FILE (``.abc``, ``.usd*``, ``.glb``, or ``.pc2``: the OBJ beside each cache
imported with the importer's defaults and a Mesh Cache modifier on it reading the cache)
into an empty scene at ``--fps``, and writes to ``--out`` each mesh object's evaluated
vertices in Blender's world (metres, Z up) at each frame, as ``NAME`` (frames, V, 3)
float64, with ``NAME.uv`` (loops, 2) and ``NAME.faces`` (F, 3) of the first frame,
``frame_offset`` (the frame glTF's time 0 lands on). ``--png`` renders the frame
``--png-frame`` with Workbench, the camera on every mesh or on ``--png-on NAME``.
Only ``bpy``, numpy and the standard library are imported.
"""

from __future__ import annotations

import argparse
import glob
import sys
from pathlib import Path

import numpy as np


def _import(path: str) -> None:
    import bpy

    suffix = path.rsplit(".", 1)[-1].lower()
    if suffix == "abc":
        bpy.ops.wm.alembic_import(filepath=path, as_background_job=False)
    elif suffix in ("usd", "usda", "usdc"):
        bpy.ops.wm.usd_import(filepath=path)
    elif suffix in ("glb", "gltf"):
        bpy.ops.import_scene.gltf(filepath=path)
    elif suffix == "pc2":
        _import_point_caches(Path(path))
    else:
        raise SystemExit(f"{path}: no Blender importer for .{suffix}")


def _import_point_caches(path: Path) -> None:
    """``STEM.pc2`` and each ``STEM_NAME.pc2`` beside it as a user opens them: the OBJ of
    the same stem imported with the importer's defaults (forward -Z, up Y), and a Mesh Cache
    modifier on it reading the cache, every setting at its default but the format (PC2;
    the default is MDD) and the file."""
    import bpy

    for cache in [path, *sorted(path.parent.glob(glob.escape(path.stem) + "_*.pc2"))]:
        before = set(bpy.data.objects)
        bpy.ops.wm.obj_import(filepath=str(cache.with_suffix(".obj")))
        (obj,) = set(bpy.data.objects) - before
        modifier = obj.modifiers.new("point cache", "MESH_CACHE")
        modifier.cache_format = "PC2"
        modifier.filepath = str(cache)


def _mesh_state(obj, depsgraph) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World vertices (V, 3), UVs per loop (L, 2) and triangles (F, 3) of the evaluated mesh."""
    ev = obj.evaluated_get(depsgraph)
    mesh = ev.to_mesh()
    co = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    M = np.array(ev.matrix_world)
    world = co @ M[:3, :3].T + M[:3, 3]
    uv = np.zeros((0, 2))
    if mesh.uv_layers:
        uv = np.empty(len(mesh.loops) * 2)
        mesh.uv_layers[0].data.foreach_get("uv", uv)
        uv = uv.reshape(-1, 2)
    faces = np.empty(len(mesh.polygons) * 3, np.int64) if len(mesh.polygons) else np.zeros(0)
    if len(mesh.polygons):
        mesh.polygons.foreach_get("vertices", faces)  # triangles only (what loosefit writes)
    ev.to_mesh_clear()
    return world, uv, faces.reshape(-1, 3)


def _render(png: str, meshes: list, distance: float = 1.0) -> None:
    """Render with Workbench to ``png``, the camera in front of ``meshes`` (each (V, 3)
    world points), ``distance`` times as far as framing them whole takes."""
    import bpy
    from mathutils import Vector

    scene = bpy.context.scene
    points = np.concatenate([m for m in meshes])
    lo, hi = points.min(0), points.max(0)
    centre, size = (lo + hi) / 2, distance * float(np.linalg.norm(hi - lo))
    cam_data = bpy.data.cameras.new("camera")
    cam = bpy.data.objects.new("camera", cam_data)
    scene.collection.objects.link(cam)
    cam.location = Vector(centre + np.array([0.9, -2.2, 0.35]) * size)
    direction = Vector(centre) - cam.location
    cam.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.display.shading.light = "STUDIO"
    scene.display.shading.color_type = "OBJECT"
    scene.render.resolution_x, scene.render.resolution_y = 480, 480
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = png
    bpy.ops.render.render(write_still=True)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("files", nargs="+", metavar="file")
    p.add_argument("--fps", type=float, required=True)
    p.add_argument("--frames", type=int, nargs="+", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--png", default=None)
    p.add_argument("--png-frame", type=int, default=0)
    p.add_argument("--png-on", default=None, help="the mesh to frame (default: every mesh)")
    p.add_argument("--png-distance", type=float, default=1.0, help="the camera's distance, x")
    args = p.parse_args(argv)

    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = round(args.fps), round(args.fps) / args.fps
    for path in args.files:
        _import(path)
    scene = bpy.context.scene
    colours = {"garment": (0.85, 0.25, 0.3, 1.0), "body": (0.75, 0.7, 0.65, 1.0)}
    # the visible meshes (glTF's importer adds a hidden one, its bones' display shape)
    objects = [o for o in scene.objects if o.type == "MESH" and o.visible_get()]
    objects.sort(key=lambda o: o.name)
    for o in objects:
        o.color = colours.get(o.name.split(".")[0], (0.5, 0.6, 0.8, 1.0))
    # glTF's animations start on frame 1 or 0 depending on the importer's version
    offset = 0
    if args.files[0].lower().endswith((".glb", ".gltf")) and bpy.data.actions:
        offset = int(round(min(a.frame_range[0] for a in bpy.data.actions)))
    seen: dict[str, list] = {o.name: [] for o in objects}
    out: dict[str, np.ndarray] = {"frame_offset": np.array(offset)}
    for f in args.frames:
        scene.frame_set(f + offset)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        for o in objects:
            world, uv, faces = _mesh_state(o, depsgraph)
            seen[o.name].append(world)
            out[f"{o.name}.uv"], out[f"{o.name}.faces"] = uv, faces
    for name, frames in seen.items():
        out[name] = np.stack(frames)
    np.savez(args.out, **out)
    if args.png:
        scene.frame_set(args.png_frame + offset)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        framed = [o for o in objects if args.png_on in (None, o.name)]
        _render(args.png, [_mesh_state(o, depsgraph)[0] for o in framed], args.png_distance)
    return 0


if __name__ == "__main__":
    sys.exit(main())
