"""Bad input (issue 6): what the user gets for each kind of broken scene. A
clear message in Blender's report naming the object, material or image
concerned, the rest of the scene still rendered where that makes sense, no
NaN or Inf pixel, and an error (so that `blender -b` exits non-zero) when
nothing could be rendered."""

import math

import bpy
import numpy as np
import pytest

import tessera.engine
from helpers import blender_render_frame, render
from scenes import add_camera, add_plane, empty_scene, principled, set_world, with_nodes

def lit_scene():
    """A grey plane filling the view under a white world, and a second,
    healthy plane the broken object must not take down with it."""
    scene = empty_scene()
    scene.render.resolution_x = scene.render.resolution_y = 16
    add_plane(20.0, location=(0, 0, -1), material=principled("Healthy", (0.5, 0.5, 0.5)))
    add_camera(scene)
    set_world(scene, (1.0, 1.0, 1.0))
    return scene


def render_tessera(scene, samples=4):
    img = render(scene, 'TESSERA', samples=samples, bounces=2)
    assert np.all(np.isfinite(img)), "NaN or Inf pixels"
    return img, tessera.engine.last_render_stats.get("warnings", [])


def one_warning_about(warnings, *words):
    hits = [w for w in warnings if all(word in w for word in words)]
    assert len(hits) == 1, f"expected one warning with {words}, got {warnings}"
    return hits[0]


def healthy_plane_rendered(img):
    # The healthy plane (albedo 0.5 under a white world, seen from above)
    # fills the frame: about 0.5 everywhere.
    mean = img[..., :3].mean()
    assert 0.35 < mean < 0.65, mean


def test_nan_and_inf_vertex_positions_skip_those_triangles_and_name_the_mesh():
    scene = lit_scene()
    obj = add_plane(1.0, location=(0, 0, 0), material=principled("Broken"))
    obj.name = "NaNPlane"
    obj.data.vertices[0].co = (math.nan, 0.0, 0.0)
    obj.data.vertices[1].co = (math.inf, 0.0, 0.0)
    img, warnings = render_tessera(scene)
    message = one_warning_about(warnings, "NaNPlane", "NaN or infinite")
    assert "not rendered" in message
    healthy_plane_rendered(img)


def test_non_finite_transform_skips_the_object_and_names_it():
    scene = lit_scene()
    obj = add_plane(1.0, material=principled("Broken"))
    obj.name = "FarAway"
    # Blender clamps a location to the float range, but a scaled parent can
    # still push the world matrix past it: 3e38 x 3e38 overflows to Inf.
    parent = bpy.data.objects.new("Huge", None)
    scene.collection.objects.link(parent)
    parent.scale = (3e38, 3e38, 3e38)
    obj.parent = parent
    obj.location = (3e38, 0.0, 0.0)
    img, warnings = render_tessera(scene)
    assert "Reset its location" in one_warning_about(warnings, "FarAway", "non-finite transform")
    healthy_plane_rendered(img)


def test_zero_scale_object_is_skipped_and_named():
    scene = lit_scene()
    obj = add_plane(1.0, material=principled("Flat"))
    obj.name = "Squashed"
    obj.scale = (0.0, 0.0, 0.0)
    img, warnings = render_tessera(scene)
    one_warning_about(warnings, "Squashed", "zero scale")
    healthy_plane_rendered(img)


def test_mesh_without_faces_is_skipped_and_named():
    scene = lit_scene()
    me = bpy.data.meshes.new("Points")
    me.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1), (1, 2)], [])
    obj = bpy.data.objects.new("Wire", me)
    scene.collection.objects.link(obj)
    img, warnings = render_tessera(scene)
    one_warning_about(warnings, "Wire", "no faces")
    healthy_plane_rendered(img)


def test_empty_scene_renders_the_world_and_says_so():
    scene = empty_scene()
    scene.render.resolution_x = scene.render.resolution_y = 8
    add_camera(scene)
    set_world(scene, (0.25, 0.5, 1.0))
    img, warnings = render_tessera(scene)
    one_warning_about(warnings, "no visible geometry")
    assert np.allclose(img[..., :3], (0.25, 0.5, 1.0), rtol=1e-5)


def test_scene_without_camera_is_an_error():
    # Blender refuses before the engine runs ("Cannot render, no camera");
    # the engine's own check (export.ExportError) covers callers that get past it.
    scene = lit_scene()
    scene.camera = None
    with pytest.raises(RuntimeError, match="no camera"):
        render(scene, 'TESSERA', samples=1, bounces=0)


def test_missing_image_file_names_the_image_and_renders_pink():
    scene = lit_scene()
    mat = principled("Textured")
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    tex = nodes.new('ShaderNodeTexImage')
    img = bpy.data.images.new("Ghost", 4, 4)
    img.source = 'FILE'
    img.filepath = "//does/not/exist.png"
    tex.image = img
    links.new(tex.outputs['Color'], nodes["Principled BSDF"].inputs['Base Color'])
    add_plane(20.0, material=mat)
    pixels, warnings = render_tessera(scene)
    message = one_warning_about(warnings, "Ghost", "could not be loaded")
    assert "Relink or pack" in message
    # Blender's missing-texture pink: red and blue, no green.
    r, g, b = pixels[..., :3].reshape(-1, 3).mean(axis=0)
    assert r > 0.3 and b > 0.3 and g < 0.05 * r, (r, g, b)


def test_unsupported_shader_node_is_named_once_and_approximated():
    scene = lit_scene()
    mat = with_nodes(bpy.data.materials.new("Toony"))
    nodes = mat.node_tree.nodes
    nodes.remove(nodes["Principled BSDF"])
    toon = nodes.new('ShaderNodeBsdfToon')
    toon.inputs['Color'].default_value = (0.5, 0.5, 0.5, 1.0)
    mat.node_tree.links.new(toon.outputs[0], nodes["Material Output"].inputs['Surface'])
    add_plane(20.0, material=mat)
    add_plane(20.0, location=(0, 0, -0.5), material=mat)  # two users, still one warning
    img, warnings = render_tessera(scene)
    one_warning_about(warnings, "Toony", "Toon")
    healthy_plane_rendered(img)


def test_zero_samples_cannot_be_set():
    scene = lit_scene()
    scene.tessera.samples = 0
    assert scene.tessera.samples == 1  # the property's minimum: Blender clamps the value


def test_resolution_beyond_memory_is_an_error_before_anything_is_allocated():
    scene = lit_scene()
    scene.render.resolution_x = scene.render.resolution_y = 65536  # 4.3 gigapixels: ~100 GiB of film
    with pytest.raises(RuntimeError, match=r"65536x65536 .* needs .* GiB"):
        render(scene, 'TESSERA', samples=1, bounces=0)


@pytest.mark.skipif(not bpy.app.binary_path, reason="needs the Blender application (not the bpy module)")
def test_headless_render_of_a_broken_scene_exits_non_zero_with_the_message(tmp_path):
    """The farm view of an error: `blender -b` prints the report and exits non-zero."""
    scene = lit_scene()
    scene.render.resolution_x = scene.render.resolution_y = 65536
    blend = str(tmp_path / "huge.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    proc = blender_render_frame(blend, tmp_path)
    assert proc.returncode != 0, proc.stdout
    assert "needs" in proc.stdout + proc.stderr and "GiB" in proc.stdout + proc.stderr
    assert not list(tmp_path.glob("f_*.png"))
