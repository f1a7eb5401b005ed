"""Writes a .blend scene's evaluated triangles, every instance placed in world
space, as one binary PLY mesh, for the BVH benchmark's interior scene
(scripts/bench_bvh.sh): the triangles a render of the scene traces, as
Tessera's export sees them (modifiers, geometry nodes, instancing). The
scene camera goes into the header as a comment the benchmark reads for its
primary rays:

    comment camera EYE_X EYE_Y EYE_Z FORWARD_X FORWARD_Y FORWARD_Z UP_X UP_Y UP_Z FOV_Y_RADIANS

Run inside Blender:

    blender -b SCENE.blend --factory-startup --python scripts/export_scene_mesh.py -- OUT.ply
"""
import math
import os
import struct
import sys

import bpy
import numpy as np
from mathutils import Vector

out = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv else None
if not out:
    sys.exit("export_scene_mesh: give the output path after --, e.g. -- /tmp/modern_hall.ply")

depsgraph = bpy.context.evaluated_depsgraph_get()
positions, faces = [], []
base = 0
for inst in depsgraph.object_instances:
    ob = inst.object
    if ob.type not in {'MESH', 'CURVE', 'SURFACE', 'META', 'FONT'}:
        continue
    mesh = ob.to_mesh()
    if mesh is None:
        continue
    mesh.calc_loop_triangles()
    nv, nt = len(mesh.vertices), len(mesh.loop_triangles)
    if nv and nt:
        co = np.empty(3 * nv, np.float32)
        mesh.vertices.foreach_get("co", co)
        co = co.reshape(-1, 3).astype(np.float64)
        m = np.array(inst.matrix_world, np.float64)
        positions.append((co @ m[:3, :3].T + m[:3, 3]).astype(np.float32))
        tri = np.empty(3 * nt, np.int32)
        mesh.loop_triangles.foreach_get("vertices", tri)
        faces.append(tri.reshape(-1, 3) + base)
        base += nv
    ob.to_mesh_clear()
if not positions:
    sys.exit(f"export_scene_mesh: {bpy.data.filepath} has no triangles to export")
positions = np.concatenate(positions)
faces = np.concatenate(faces)

header = ["ply", "format binary_little_endian 1.0",
          f"comment triangles of {os.path.basename(bpy.data.filepath)} in world space (scripts/export_scene_mesh.py)"]
cam = bpy.context.scene.camera
if cam is not None and cam.type == 'CAMERA':
    mw = cam.matrix_world
    eye = mw.translation
    fwd = (mw.to_3x3() @ Vector((0.0, 0.0, -1.0))).normalized()
    up = (mw.to_3x3() @ Vector((0.0, 1.0, 0.0))).normalized()
    r = bpy.context.scene.render
    aspect = (r.resolution_x * r.pixel_aspect_x) / max(1e-9, r.resolution_y * r.pixel_aspect_y)
    fov = cam.data.angle
    # Blender's angle spans the larger image side (sensor fit Auto).
    fov_y = fov if aspect < 1.0 else 2.0 * math.atan(math.tan(0.5 * fov) / aspect)
    header.append("comment camera " + " ".join(f"{v:.9g}" for v in (*eye, *fwd, *up, fov_y)))
header += [f"element vertex {len(positions)}", "property float x", "property float y", "property float z",
           f"element face {len(faces)}", "property list uchar int vertex_indices", "end_header"]
face_records = np.empty(len(faces), dtype=[("n", "u1"), ("v", "<i4", 3)])
face_records["n"] = 3
face_records["v"] = faces
with open(out, "wb") as f:
    f.write(("\n".join(header) + "\n").encode())
    f.write(positions.astype("<f4").tobytes())
    f.write(face_records.tobytes())
print(f"export_scene_mesh: {len(faces)} triangles, {len(positions)} vertices -> {out}")
