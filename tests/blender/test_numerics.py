"""Numerical soundness through Blender's export (issue 6): a closed, all-diffuse
room lit by an emissive quad, scaled by a parent from 1e-4 to 1e4 and moved
1e5 units from the origin the way users move scenes (object transforms),
renders the image of the unit-scale room at the origin."""

import bpy
import numpy as np
import pytest

from helpers import render
from scenes import empty_scene, principled, set_world


def room(scale=1.0, location=(0.0, 0.0, 0.0)):
    scene = empty_scene()
    scene.render.resolution_x = scene.render.resolution_y = 24
    set_world(scene, (0.0, 0.0, 0.0))
    root = bpy.data.objects.new("Root", None)
    scene.collection.objects.link(root)
    # The room: a 2 m cube seen from inside, one red wall.
    bpy.ops.mesh.primitive_cube_add(size=2.0)
    box = bpy.context.object
    box.data.materials.append(principled("White", (0.7, 0.7, 0.7)))
    box.data.materials.append(principled("Red", (0.7, 0.1, 0.1)))
    box.data.polygons[0].material_index = 1
    # The light: a 0.6 m emissive quad 1 cm under the ceiling, both sides lit.
    bpy.ops.mesh.primitive_plane_add(size=0.6, location=(0, 0, 0.99))
    lamp = bpy.context.object
    lamp.data.materials.append(principled("Lamp", (0, 0, 0), **{"Emission": (1, 1, 1, 1), "Emission Strength": 10.0}))
    bpy.ops.object.camera_add(location=(0, -0.95, 0), rotation=(1.5708, 0, 0))
    cam = bpy.context.object
    cam.data.lens = 18.0
    cam.data.clip_start, cam.data.clip_end = 0.01 * scale, 100.0 * scale
    scene.camera = cam
    for obj in (box, lamp, cam):
        obj.parent = root
    root.scale = (scale, scale, scale)
    root.location = location
    return scene


@pytest.fixture(scope="module")
def unit_image():
    return render(room(), 'TESSERA', samples=32, bounces=8)


@pytest.mark.parametrize("scale, location", [(1e-4, 0.0), (1e-2, 0.0), (1e2, 0.0), (1e4, 0.0), (1.0, 1e5)],
                         ids=["scale 1e-4", "scale 1e-2", "scale 1e2", "scale 1e4", "moved 1e5"])
def test_room_renders_the_same_at_every_scale_and_far_away(unit_image, scale, location):
    img = render(room(scale, (location, -location, location)), 'TESSERA', samples=32, bounces=8)
    assert np.all(np.isfinite(img))
    ratio = img[..., :3].reshape(-1, 3).mean(axis=0) / unit_image[..., :3].reshape(-1, 3).mean(axis=0)
    print(f"scale {scale:g}, {location:g} from the origin: mean ratio {ratio}")
    assert np.all(np.abs(ratio - 1.0) < 0.02), ratio
