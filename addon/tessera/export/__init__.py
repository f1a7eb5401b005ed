"""Turns the evaluated Blender scene (the depsgraph) into the core's Scene,
one module per Blender concept. No file is written; every array goes to the
core through the buffer protocol."""

import time

from .. import core
from . import camera, lights, materials, mesh, world


class ExportError(Exception):
    """The scene cannot be rendered; the message says why and what to do."""


class Report:
    """Collects warnings once per subject, for the engine to show."""

    def __init__(self):
        self.warnings = []
        self._seen = set()

    def warn(self, subject, message):
        if (subject, message) not in self._seen:
            self._seen.add((subject, message))
            self.warnings.append(message)


# Object Properties > Visibility > Ray Visibility, as Cycles names the rays,
# and the core's ray kinds (visibility.h). Volume Scatter has no ray in
# Tessera (no volumes), so it changes nothing.
_SCATTERED = (("visible_diffuse", "RAY_DIFFUSE"), ("visible_glossy", "RAY_GLOSSY"),
              ("visible_transmission", "RAY_TRANSMISSION"))


def ray_visibility(obj, report):
    """The object's ray visibility as the core's mask: the ray kinds that see
    it. For a light, the kinds it lights, Camera (off by default) that camera
    rays see it, and Shadow that it casts shadows (the light's Cast Shadow).
    Warns about the visibility settings Tessera does not model."""
    mask = core.ray_mask(obj, _SCATTERED)
    if obj.type == 'LIGHT':
        mask |= core.ray_mask(obj, (("visible_camera", "RAY_CAMERA"),), default=False)
        return mask | (core.native.RAY_SHADOW if lights.casts_shadow(obj.data) else 0)
    mask |= core.ray_mask(obj, (("visible_camera", "RAY_CAMERA"), ("visible_shadow", "RAY_SHADOW")))
    for attr, label in (("is_holdout", "Holdout"), ("is_shadow_catcher", "Shadow Catcher")):
        if getattr(obj, attr, False):
            report.warn(obj.name, f"Object '{obj.name}' is a {label} (Object Properties > Visibility), which "
                                  f"Tessera does not model: it renders as an ordinary object.")
    return mask


def check_film(bl_scene, report):
    """Warns about Film settings that Tessera does not model."""
    cycles_settings = getattr(bl_scene, "cycles", None)
    if bl_scene.render.film_transparent and getattr(cycles_settings, "film_transparent_glass", False):
        report.warn(bl_scene.name, "Film > Transparent Glass is not modelled: the world seen through glass stays "
                                   "opaque. Turn it off to get Cycles' image.")


def export_scene(depsgraph, width, height, is_cancelled=lambda: False, camera_override=None):
    """Returns (core Scene, stats dict, Report). Raises ExportError.
    camera_override: the camera to render through instead of the scene's."""
    t0 = time.perf_counter()
    report = Report()
    scene_core = core.native.Scene()
    bl_scene = depsgraph.scene

    cam = camera.export_camera(depsgraph, width, height, report, camera_override)
    if cam is None:
        raise ExportError(
            f"Scene '{bl_scene.name}' has no active camera. Add a camera and make it active "
            f"(Scene Properties > Camera), or pass one with --python-expr.")
    scene_core.set_camera(**cam)

    mat_cache = materials.MaterialCache(scene_core, report, bl_scene.tessera.diffuse_texture_blur)
    mesh_cache = mesh.MeshCache(scene_core, report)
    num_instances = 0
    for inst in depsgraph.object_instances:
        if is_cancelled():
            return None, None, report
        obj = inst.object
        if obj.type == 'LIGHT':
            lights.export_light(scene_core, obj, inst.matrix_world, report, ray_visibility(obj, report))
            continue
        if obj.type not in mesh.GEOMETRY_TYPES:
            continue
        if not inst.show_self and not inst.is_instance:
            continue  # an instancer that only shows its instances
        slot_materials = [mat_cache.get(slot.material) for slot in obj.material_slots]
        need_uvs = any(mat_cache.needs_uvs(slot.material) for slot in obj.material_slots)
        mesh_id = mesh_cache.get(obj, need_uvs)
        if mesh_id is None:
            continue
        matrix = mesh.matrix_array(inst.matrix_world, obj.name, report)
        if matrix is None:
            continue
        scene_core.add_instance(mesh_id, matrix, slot_materials, ray_visibility(obj, report))
        num_instances += 1

    world.export_world(scene_core, bl_scene.world, report)
    check_film(bl_scene, report)
    export_seconds = time.perf_counter() - t0
    t1 = time.perf_counter()
    scene_core.commit()
    stats = {
        "export_seconds": export_seconds - mesh_cache.build_seconds,
        "blas_build_seconds": mesh_cache.build_seconds,
        "tlas_build_seconds": time.perf_counter() - t1,
        "triangles": scene_core.num_triangles,
        "instanced_triangles": scene_core.num_instanced_triangles,
        "instances": num_instances,
        "meshes": scene_core.num_meshes,
        "memory_bytes": scene_core.memory_bytes,
    }
    return scene_core, stats, report
