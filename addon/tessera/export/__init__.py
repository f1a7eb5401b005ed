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


# Object Properties > Visibility > Ray Visibility, as Cycles names the rays.
_RAY_VISIBILITY = (("visible_camera", "Camera"), ("visible_diffuse", "Diffuse"), ("visible_glossy", "Glossy"),
                   ("visible_transmission", "Transmission"), ("visible_volume_scatter", "Volume Scatter"),
                   ("visible_shadow", "Shadow"))
_SCATTERED_RAYS = _RAY_VISIBILITY[1:4]  # what a light's visibility can turn off: Diffuse, Glossy, Transmission


def check_ray_visibility(obj, report):
    """Warns about the object's visibility settings that Tessera does not
    model. Of an object's ray visibility it models Camera (the instance is
    passed by camera rays); every other ray sees it and it casts shadows.
    Lights are unseen by the camera and light every surface, as Cycles'
    defaults have them."""
    if obj.type == 'LIGHT':
        seen = [label for attr, label in _SCATTERED_RAYS if not getattr(obj, attr, True)]
        if seen:
            report.warn(obj.name, f"Light '{obj.name}' has ray visibility off for {', '.join(seen)} (Object "
                                  f"Properties > Visibility), which Tessera does not model: it lights every "
                                  f"surface. Turn those rays back on to get Cycles' image.")
        if getattr(obj, "visible_camera", False):
            report.warn(obj.name, f"Light '{obj.name}' is visible to the camera (Object Properties > Visibility), "
                                  f"which Tessera does not model: the camera does not see it. Turn Camera "
                                  f"visibility off to get Cycles' image.")
        return
    off = [label for attr, label in _RAY_VISIBILITY if attr != "visible_camera" and not getattr(obj, attr, True)]
    if off:
        report.warn(obj.name, f"Object '{obj.name}' has ray visibility off for {', '.join(off)} (Object Properties "
                              f"> Visibility), which Tessera does not model: every ray sees it and it casts "
                              f"shadows. Turn those rays back on, or hide the object, to get Cycles' image.")
    for attr, label in (("is_holdout", "Holdout"), ("is_shadow_catcher", "Shadow Catcher")):
        if getattr(obj, attr, False):
            report.warn(obj.name, f"Object '{obj.name}' is a {label} (Object Properties > Visibility), which "
                                  f"Tessera does not model: it renders as an ordinary object.")


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

    mat_cache = materials.MaterialCache(scene_core, report)
    mesh_cache = mesh.MeshCache(scene_core, report)
    num_instances = 0
    for inst in depsgraph.object_instances:
        if is_cancelled():
            return None, None, report
        obj = inst.object
        if obj.type == 'LIGHT':
            check_ray_visibility(obj, report)
            lights.export_light(scene_core, obj, inst.matrix_world, report)
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
        check_ray_visibility(obj, report)
        scene_core.add_instance(mesh_id, matrix, slot_materials, bool(getattr(obj, "visible_camera", True)))
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
