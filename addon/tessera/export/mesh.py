"""Meshes: each unique evaluated mesh is exported once (its BLAS is built in
object space) however many instances use it. Bulk foreach_get into numpy
buffers only; no Python loop over vertices or triangles."""

import time

import bpy
import numpy as np

GEOMETRY_TYPES = {'MESH', 'CURVE', 'SURFACE', 'FONT', 'META'}

_HAS_CORNER_NORMALS = bpy.app.version >= (4, 1, 0)


def matrix_array(matrix, name, report):
    m = np.array(matrix, dtype=np.float32)
    if not np.all(np.isfinite(m)):
        report.warn(name, f"Object '{name}' has a non-finite transform (NaN or Inf); it is not rendered. "
                          f"Reset its location, rotation and scale.")
        return None
    if abs(np.linalg.det(m[:3, :3].astype(np.float64))) < 1e-30:
        report.warn(name, f"Object '{name}' has zero scale; it is not rendered. Give it a non-zero scale.")
        return None
    return m


def _mesh_key(obj):
    # Evaluated meshes shared by several objects or instances (linked
    # duplicates, collection and geometry-nodes instances) share one pointer.
    if obj.type == 'MESH' and obj.data is not None:
        return ("mesh", obj.data.as_pointer())
    return ("object", obj.original.as_pointer() if obj.original else obj.as_pointer())


def mesh_arrays(me, need_uvs=False):
    """Flat arrays of an evaluated mesh: positions (V,3) float32, indices (T,3)
    uint32, material slots (T) uint32, corner normals (3T,3) float32 or None."""
    me.calc_loop_triangles()
    nt = len(me.loop_triangles)
    nv = len(me.vertices)
    positions = np.empty(nv * 3, dtype=np.float32)
    me.vertices.foreach_get("co", positions)
    indices = np.empty(nt * 3, dtype=np.uint32)
    me.loop_triangles.foreach_get("vertices", indices)
    slots = np.empty(nt, dtype=np.uint32)
    me.loop_triangles.foreach_get("material_index", slots)
    smooth = np.empty(nt, dtype=bool)
    me.loop_triangles.foreach_get("use_smooth", smooth)
    normals = None
    tri_loops = None
    if smooth.any():
        tri_loops = np.empty(nt * 3, dtype=np.uint32)
        me.loop_triangles.foreach_get("loops", tri_loops)
        loop_normals = np.empty(len(me.loops) * 3, dtype=np.float32)
        if _HAS_CORNER_NORMALS:
            me.corner_normals.foreach_get("vector", loop_normals)
        else:
            me.calc_normals_split()
            me.loops.foreach_get("normal", loop_normals)
        normals = loop_normals.reshape(-1, 3)[tri_loops]
    uvs = None
    if need_uvs and me.uv_layers.active is not None:
        if tri_loops is None:
            tri_loops = np.empty(nt * 3, dtype=np.uint32)
            me.loop_triangles.foreach_get("loops", tri_loops)
        loop_uvs = np.empty(len(me.loops) * 2, dtype=np.float32)
        me.uv_layers.active.data.foreach_get("uv", loop_uvs)
        uvs = loop_uvs.reshape(-1, 2)[tri_loops]
    return positions.reshape(-1, 3), indices.reshape(-1, 3), slots, normals, uvs


class MeshCache:
    def __init__(self, scene_core, report):
        self.scene = scene_core
        self.report = report
        self.ids = {}
        self.build_seconds = 0.0

    def get(self, obj, need_uvs=False):
        key = _mesh_key(obj) + (need_uvs,)
        if key in self.ids:
            return self.ids[key]
        mesh_id = None
        try:
            me = obj.to_mesh()
        except RuntimeError:
            me = None
        if me is not None:
            try:
                if len(me.polygons) == 0:
                    if obj.type == 'MESH' and len(me.vertices) > 0:
                        self.report.warn(obj.name, f"Mesh object '{obj.name}' has no faces; it is not rendered.")
                else:
                    positions, indices, slots, normals, uvs = mesh_arrays(me, need_uvs)
                    t0 = time.perf_counter()
                    mesh_id = self.scene.add_mesh(positions, indices, slots, normals, uvs)
                    self.build_seconds += time.perf_counter() - t0
                    skipped = self.scene.mesh_skipped_triangles(mesh_id)
                    if skipped:
                        self.report.warn(obj.name, f"Mesh '{obj.name}': {skipped} triangles have NaN or infinite "
                                                   f"vertex positions and are not rendered. Fix the mesh data or "
                                                   f"the modifier that produced them.")
            finally:
                obj.to_mesh_clear()
        self.ids[key] = mesh_id
        return mesh_id
