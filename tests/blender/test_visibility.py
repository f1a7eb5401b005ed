"""Ray visibility against Cycles (Object, Light and World Properties >
Visibility > Ray Visibility, and a light's Cast Shadow): each case turns one
setting off (or a light's Camera on) in one small scene and must change
Cycles' image well beyond the tolerance Tessera is then held to. Before
Tessera modelled them, every case rendered as the scene without the change
(and a warning said the setting was ignored)."""

import math

import bpy
import numpy as np
import pytest

from helpers import compare, render
from scenes import add_camera, add_plane, empty_scene, principled, set_world

SAMPLES = 512
BOUNCES = 4


def visibility_scene():
    """A floor seen at an angle, with a red wall that bleeds onto it, a cube
    that casts a shadow, a mirror that shows the cube, a rough glass pane the
    camera sees the cube through, a softbox (an emissive plane) and an area
    light, under a dim blue world. Returns the scene and its objects by role."""
    scene = empty_scene()
    scene.render.resolution_x, scene.render.resolution_y = 64, 48
    add_plane(14.0, material=principled("Floor", (0.8, 0.8, 0.8), Specular=0.0, Roughness=1.0))
    wall = add_plane(2.4, location=(1.5, 0.6, 1.2), rotation=(0, math.radians(90), 0),
                     material=principled("Red", (0.8, 0.05, 0.05), Specular=0.0, Roughness=1.0))
    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(0.2, -0.2, 0.4))
    cube = bpy.context.object
    cube.data.materials.append(principled("Cube", (0.2, 0.7, 0.2), Specular=0.0, Roughness=1.0))
    mirror = add_plane(1.6, location=(-1.7, 0.3, 0.9), rotation=(math.radians(90), 0, math.radians(50)),
                       material=principled("Mirror", (0.9, 0.9, 0.9), Metallic=1.0, Roughness=0.25))
    glass = add_plane(0.9, location=(0.35, -1.3, 0.45), rotation=(math.radians(90), 0, 0),
                      material=principled("Glass", (1.0, 1.0, 1.0), Transmission=1.0, Roughness=0.1, IOR=1.45))
    softbox = add_plane(0.8, location=(-0.6, 1.6, 1.7), rotation=(math.radians(180), 0, 0),
                        material=principled("Softbox", (0.0, 0.0, 0.0), Specular=0.0, **{
                            ("Emission Color" if bpy.app.version >= (4, 0, 0) else "Emission"): (1.0, 0.9, 0.7, 1.0),
                            "Emission Strength": 6.0}))
    bpy.ops.object.light_add(type='AREA', location=(0.8, 0.2, 2.6))
    light = bpy.context.object
    light.data.energy = 150.0
    light.data.size = 0.8
    add_camera(scene, location=(0, -5.5, 3.2), rotation=(math.radians(62), 0, 0), lens=30)
    world = set_world(scene, (0.3, 0.4, 0.6), 0.6)
    return scene, dict(wall=wall, cube=cube, mirror=mirror, glass=glass, softbox=softbox, light=light, world=world)


def cast_shadow_off(light):
    if hasattr(light.data.cycles, "cast_shadow"):  # Blender 3.x: Cycles' own setting
        light.data.cycles.cast_shadow = False
    else:
        light.data.use_shadow = False


def light_facing_the_camera(light):
    """Visible to the camera, and turned to face it (area lights are one-sided)."""
    light.visible_camera = True
    light.rotation_euler = (math.radians(-45), 0, 0)


CASES = {
    "cube_casts_no_shadow": lambda o: setattr(o["cube"], "visible_shadow", False),
    "wall_unseen_by_diffuse_rays": lambda o: setattr(o["wall"], "visible_diffuse", False),
    "cube_unseen_by_glossy_rays": lambda o: setattr(o["cube"], "visible_glossy", False),
    "cube_unseen_by_transmission_rays": lambda o: setattr(o["cube"], "visible_transmission", False),
    "softbox_unseen_by_diffuse_rays": lambda o: setattr(o["softbox"], "visible_diffuse", False),
    "light_unseen_by_diffuse_rays": lambda o: setattr(o["light"], "visible_diffuse", False),
    "light_unseen_by_glossy_rays": lambda o: setattr(o["light"], "visible_glossy", False),
    "light_seen_by_the_camera": lambda o: light_facing_the_camera(o["light"]),
    "light_casts_no_shadow": lambda o: cast_shadow_off(o["light"]),
    "world_unseen_by_the_camera": lambda o: setattr(o["world"].cycles_visibility, "camera", False),
    "world_unseen_by_diffuse_rays": lambda o: setattr(o["world"].cycles_visibility, "diffuse", False),
}

_cycles_base = {}


def cycles_base():
    if "image" not in _cycles_base:
        scene, _ = visibility_scene()
        _cycles_base["image"] = render(scene, 'CYCLES', samples=SAMPLES, bounces=BOUNCES)
    return _cycles_base["image"]


@pytest.mark.parametrize("case", sorted(CASES))
def test_ray_visibility_matches_cycles(case):
    # Cycles without the change first: each scene starts from factory settings.
    if case == "light_seen_by_the_camera":  # the change is the light's front in view, not its turn
        base_scene, base_objects = visibility_scene()
        base_objects["light"].rotation_euler = (math.radians(-45), 0, 0)
        base = render(base_scene, 'CYCLES', samples=SAMPLES, bounces=BOUNCES)
    else:
        base = cycles_base()
    scene, objects = visibility_scene()
    CASES[case](objects)
    ours = render(scene, 'TESSERA', samples=SAMPLES, bounces=BOUNCES)
    ref = render(scene, 'CYCLES', samples=SAMPLES, bounces=BOUNCES)
    change = compare(ref, base)
    c = compare(ours, ref)
    print(case, "Cycles' change:", {k: np.round(v, 4) for k, v in change.items()})
    print(case, "Tessera vs Cycles:", {k: np.round(v, 4) for k, v in c.items()})
    assert np.all(np.isfinite(ours))
    # Tessera matches Cycles with the setting, and far better than Cycles'
    # image without it would: what Tessera rendered before modelling it.
    assert np.all(c["mean_rel_diff"] < 0.02), f"mean {c['mean_test']} vs Cycles {c['mean_ref']}"
    assert c["rel_rmse"] < min(0.04, 0.5 * change["rel_rmse"]), (c, change)
    assert c["worst_block"] < 0.15, c
