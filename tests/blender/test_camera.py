"""The camera against Cycles: depth of field (thin lens from the f-stop, a
focus object or distance, aperture blades, rotation and ratio)."""

import bpy
import numpy as np
import pytest
from bpy_extras.object_utils import world_to_camera_view

from helpers import compare, downsample, render
from scenes import add_camera, add_plane, empty_scene, principled, set_world

# name, colour, distance from the camera (m), x offset (m), radius (m)
BALLS = (("Near", (0.9, 0.2, 0.1), 3.0, -0.45, 0.15), ("Mid", (0.1, 0.8, 0.2), 5.0, 0.1, 0.2),
         ("Far", (0.1, 0.3, 0.9), 9.0, 1.3, 0.4))


def dof_scene(focus_object=True, fstop=0.2, blades=0, rotation=0.0, ratio=1.0):
    """Three coloured balls at 3, 5 and 9 m before a bright world, seen with
    an 85 mm lens; the middle one in focus (by object or by distance). At
    f/0.2 the near ball's edge is blurred over ~9 pixels, the far one's ~6."""
    scene = empty_scene()
    add_plane(60.0, location=(0, 0, -0.6), material=principled("Floor", (0.4, 0.4, 0.4), Specular=0.0, Roughness=1.0))
    for name, color, dist, x, radius in BALLS:
        bpy.ops.mesh.primitive_uv_sphere_add(radius=radius, location=(x, dist - 4.0, 0.0), segments=48, ring_count=24)
        bpy.ops.object.shade_smooth()
        obj = bpy.context.object
        obj.name = name
        obj.data.materials.append(principled(name, color, Specular=0.2, Roughness=0.6))
    cam = add_camera(scene, location=(0, -4.0, 0.0), rotation=(np.radians(90), 0, 0), lens=85)
    dof = cam.data.dof
    dof.use_dof = True
    dof.aperture_fstop = fstop
    dof.aperture_blades = blades
    dof.aperture_rotation = rotation
    dof.aperture_ratio = ratio
    if focus_object:
        dof.focus_object = bpy.data.objects["Mid"]
        dof.focus_distance = 100.0  # ignored with a focus object
    else:
        dof.focus_distance = 5.0
    set_world(scene, (0.9, 0.9, 1.0), 1.0)
    bpy.ops.object.light_add(type='SUN', rotation=(np.radians(40), 0, np.radians(30)))
    bpy.context.object.data.energy = 3.0
    scene.render.resolution_x, scene.render.resolution_y = 128, 96
    return scene


def edge_contrast(scene, img, name):
    """Steepest luminance step (per pixel) of the image row profile through
    the ball's middle (mean of the rows within 0.3 radius of its centre,
    columns to 1.3 radii either side): lower when the edges are blurred."""
    obj = bpy.data.objects[name]
    h, w = img.shape[:2]
    c = world_to_camera_view(scene, scene.camera, obj.location)
    side = obj.location + obj.dimensions.x / 2 * obj.matrix_world.col[0].xyz.normalized()
    cx, cy = c.x * w, (1.0 - c.y) * h  # rows top to bottom
    r = (world_to_camera_view(scene, scene.camera, side).x - c.x) * w
    rows = slice(int(cy - 0.3 * r), int(cy + 0.3 * r) + 1)
    cols = slice(max(int(cx - 1.3 * r), 0), min(int(cx + 1.3 * r) + 1, w))
    profile = img[rows, cols, :3].mean(axis=(0, 2))
    return float(np.abs(np.diff(profile)).max())


def _worst_block8(ours, ref):
    dt, dr = downsample(ours, 8), downsample(ref, 8)
    return float(np.max(np.abs(dt - dr).mean(axis=-1) / np.maximum(dr.mean(axis=-1), 0.1 * dr.mean())))


@pytest.mark.parametrize("variant", [
    dict(focus_object=True),
    dict(focus_object=False, blades=6, rotation=0.4),
    dict(focus_object=True, fstop=0.4, blades=5, ratio=1.6),
])
def test_depth_of_field_matches_cycles(variant):
    scene = dof_scene(**variant)
    ours = render(scene, 'TESSERA', samples=256, bounces=2)
    ref = render(scene, 'CYCLES', samples=256, bounces=2)
    c = compare(ours, ref)
    c["worst_block8"] = _worst_block8(ours, ref)
    edges = {n: (round(edge_contrast(scene, ours, n), 4), round(edge_contrast(scene, ref, n), 4)) for n, *_ in BALLS}
    print(variant, {k: np.round(v, 4) for k, v in c.items()}, "edge contrast (ours, Cycles)", edges)
    assert np.all(np.isfinite(ours))
    assert np.all(c["mean_rel_diff"] < 0.02), c
    assert c["rel_rmse"] < 0.05, c
    assert c["worst_block8"] < 0.15, c
    # The edges are as sharp or as blurred as Cycles' (noise aside).
    for name, (a, b) in edges.items():
        assert abs(a - b) < 0.2 * b + 0.025, (name, a, b)  # blurred edges: steps of a few % are noise


def test_only_the_focus_plane_is_sharp():
    """The ball in focus keeps its edge; the nearer and farther ones are blurred."""
    scene = dof_scene()
    ours = render(scene, 'TESSERA', samples=128, bounces=1)
    scene.camera.data.dof.use_dof = False
    pinhole = render(scene, 'TESSERA', samples=128, bounces=1)
    ratio = {n: edge_contrast(scene, ours, n) / edge_contrast(scene, pinhole, n) for n, *_ in BALLS}
    print("edge contrast with / without depth of field", ratio)
    assert ratio["Mid"] > 0.75, ratio
    assert ratio["Near"] < 0.4 and ratio["Far"] < 0.5, ratio
