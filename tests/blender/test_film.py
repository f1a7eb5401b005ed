"""What the camera sees, against Cycles: Film > Transparent (the world left
out, alpha from the paths), objects hidden from the camera (Object Properties
> Visibility > Camera), and the warnings for the settings Tessera does not
model."""

import math

import bpy
import numpy as np

from helpers import compare, render
from scenes import add_camera, add_plane, empty_scene, principled, set_world


def transparent_film_scene():
    """A plane, half Lambert and half see-through (a Principled Alpha of 0.3),
    on a bright blue world, tilted before a camera that sees the world around
    it: the world lights the plane and shows at the edges and through it."""
    scene = empty_scene()
    add_plane(2.0, location=(-1.0, 0, 0), rotation=(math.radians(20), 0, 0),
              material=principled("Opaque", (0.8, 0.5, 0.3), Specular=0.0, Roughness=1.0))
    add_plane(2.0, location=(1.0, 0, 0), rotation=(math.radians(20), 0, 0),
              material=principled("Clear", (0.3, 0.5, 0.8), Specular=0.0, Roughness=1.0, Alpha=0.3))
    add_camera(scene, location=(0, 0, 6), lens=35)
    set_world(scene, (0.6, 0.8, 1.0), 1.5)
    scene.render.film_transparent = True
    scene.render.image_settings.color_mode = 'RGBA'
    return scene


def test_transparent_film_matches_cycles():
    """Before Tessera modelled Film > Transparent, alpha was 1 everywhere and
    the world's blue filled the background (mean alpha 1 against Cycles' 0.13)."""
    scene = transparent_film_scene()
    ours = render(scene, 'TESSERA', samples=64, bounces=4)
    ref = render(scene, 'CYCLES', samples=64, bounces=4)
    alpha_t, alpha_c = ours[..., 3], ref[..., 3]
    print(f"alpha mean Tessera {alpha_t.mean():.4f}, Cycles {alpha_c.mean():.4f}; "
          f"RMSE {np.sqrt(np.mean((alpha_t - alpha_c) ** 2)):.4f}")
    assert np.all(np.isfinite(ours))
    assert abs(alpha_t.mean() - alpha_c.mean()) < 0.01
    assert np.sqrt(np.mean((alpha_t - alpha_c) ** 2)) < 0.05
    # Where Cycles sees only the world (2 pixels off anything else, past the
    # filters' edges), Tessera too: nothing in colour or alpha.
    seen = alpha_c > 0.0
    near = seen.copy()
    for dy in (-2, -1, 1, 2):
        near |= np.roll(seen, dy, axis=0)
    for dx in (-2, -1, 1, 2):
        near |= np.roll(near, dx, axis=1)
    world = ~near
    assert world.sum() > 0.2 * world.size
    assert np.all(ours[world] == 0.0)
    c = compare(ours, ref)
    print({k: np.round(v, 4) for k, v in c.items()})
    assert np.all(c["mean_rel_diff"] < 0.02), f"mean {c['mean_test']} vs Cycles {c['mean_ref']}"
    assert c["rel_rmse"] < 0.05, c


def test_opaque_film_keeps_the_world_and_alpha_one():
    scene = transparent_film_scene()
    scene.render.film_transparent = False
    ours = render(scene, 'TESSERA', samples=16, bounces=4)
    assert np.all(ours[..., 3] == 1.0)
    corner = ours[0, 0, :3]
    assert np.allclose(corner, (0.9, 1.2, 1.5), rtol=1e-5), corner


def test_unmodelled_visibility_and_film_settings_are_named():
    """Holdout, Shadow Catcher and Transparent Glass change Cycles' image and
    Tessera does not model them: each is named in a warning (they were
    ignored silently). Ray visibility is modelled (test_visibility.py) and
    warns no more."""
    from tessera import engine
    scene = transparent_film_scene()
    opaque = bpy.data.objects["Plane"]
    opaque.visible_shadow = False
    opaque.is_shadow_catcher = True
    clear = bpy.data.objects["Plane.001"]
    clear.is_holdout = True
    scene.world.cycles_visibility.camera = False
    scene.cycles.film_transparent_glass = True
    bpy.ops.object.light_add(type='AREA', location=(0, 0, 3))
    light = bpy.context.object
    light.visible_camera = True
    render(scene, 'TESSERA', samples=1, bounces=1)
    warnings = engine.last_render_stats.get("warnings", [])
    text = " | ".join(warnings)
    print(text)
    assert any(opaque.name in w and "Shadow Catcher" in w for w in warnings), text
    assert any(clear.name in w and "Holdout" in w for w in warnings), text
    assert any("Transparent Glass" in w for w in warnings), text
    assert not any("visibility" in w for w in warnings), text


def test_objects_hidden_from_the_camera_match_cycles():
    """A softbox (an emissive plane) and a cube hidden from the camera over a
    floor: the camera sees the floor they light and shade, not them. Before
    Tessera modelled Camera visibility it showed both (the softbox as a white
    rectangle)."""
    scene = empty_scene()
    add_plane(12.0, material=principled("Floor", (0.8, 0.8, 0.8), Specular=0.0, Roughness=1.0))
    softbox = add_plane(1.5, location=(0.8, 0.3, 1.2), rotation=(math.radians(180), 0, 0),
                        material=principled("Softbox", (0.0, 0.0, 0.0), Specular=0.0, **{
                            ("Emission Color" if bpy.app.version >= (4, 0, 0) else "Emission"): (1.0, 1.0, 1.0, 1.0),
                            "Emission Strength": 8.0}))
    softbox.visible_camera = False
    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(-0.9, -0.2, 0.4))
    cube = bpy.context.object
    cube.data.materials.append(principled("Cube", (0.8, 0.2, 0.1), Specular=0.0, Roughness=1.0))
    cube.visible_camera = False
    add_camera(scene, location=(0, 0, 5), lens=35)
    set_world(scene, (0.05, 0.05, 0.05), 1.0)
    ours = render(scene, 'TESSERA', samples=128, bounces=4)
    ref = render(scene, 'CYCLES', samples=128, bounces=4)
    c = compare(ours, ref)
    print({k: np.round(v, 4) for k, v in c.items()})
    assert np.all(np.isfinite(ours))
    assert np.all(c["mean_rel_diff"] < 0.02), f"mean {c['mean_test']} vs Cycles {c['mean_ref']}"
    assert c["rel_rmse"] < 0.05, c
    # The softbox lights the floor but is not seen: nothing near its radiance.
    assert ours[..., :3].max() < 4.0, ours[..., :3].max()
