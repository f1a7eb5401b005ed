"""Materials against Cycles on small scenes built here: image textures with
the mesh's UV map, the Principled BSDF over roughness, metallic and IOR, and
the other shader nodes (Mix and Add Shader, Diffuse, Glossy, Glass,
Transparent, Principled Alpha from a value or an image)."""

import bpy
import numpy as np
import pytest

from helpers import compare, downsample, render
from scenes import add_camera, add_plane, empty_scene, principled, set_world, with_nodes


def textured_plane_scene(interpolation='Linear', extension='REPEAT', scale=1.0):
    scene = empty_scene()
    img = bpy.data.images.new("grid", 64, 64)
    img.generated_type = 'COLOR_GRID'
    mat = principled("Textured", Specular=0.0, Roughness=1.0)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    tex = nodes.new('ShaderNodeTexImage')
    tex.image = img
    tex.interpolation = interpolation
    tex.extension = extension
    if scale != 1.0:
        mapping = nodes.new('ShaderNodeMapping')
        coord = nodes.new('ShaderNodeTexCoord')
        mapping.inputs['Scale'].default_value = (scale, scale, 1.0)
        links.new(coord.outputs['UV'], mapping.inputs['Vector'])
        links.new(mapping.outputs['Vector'], tex.inputs['Vector'])
    links.new(tex.outputs['Color'], nodes["Principled BSDF"].inputs['Base Color'])
    add_plane(2.0, material=mat)
    add_camera(scene, location=(0, 0, 3.0), lens=40)
    set_world(scene, (1.0, 1.0, 1.0), 1.0)
    return scene


@pytest.mark.parametrize("interpolation", ['Closest', 'Linear'])
def test_image_texture_matches_cycles(interpolation):
    scene = textured_plane_scene(interpolation)
    scene.render.resolution_x = scene.render.resolution_y = 96
    ours = render(scene, 'TESSERA', samples=64, bounces=1)
    ref = render(scene, 'CYCLES', samples=64, bounces=1)
    c = compare(ours, ref)
    print(interpolation, {k: np.round(v, 4) for k, v in c.items()})
    assert np.all(c["mean_rel_diff"] < 0.02), c
    assert c["rel_rmse"] < 0.05, c
    assert c["worst_block"] < 0.15, c


def test_texture_through_unsupported_nodes_is_named_in_a_warning():
    from tessera import engine
    scene = textured_plane_scene(scale=2.0)  # Mapping node: not sampled per pixel yet
    scene.render.resolution_x = scene.render.resolution_y = 16
    render(scene, 'TESSERA', samples=1, bounces=0)
    warnings = " ".join(engine.last_render_stats.get("warnings", []))
    assert "Textured" in warnings and "average colour" in warnings, warnings


def test_texture_average_is_read_again_at_every_render():
    """A texture Tessera approximates by its average colour follows the image
    when it changes between renders (painted, reloaded). The averages were
    kept across renders by the image's address: this image kept its first
    average, and a new image at a freed one's address got that one's (a
    bpy 4.5 CI run lost the warning of the test above that way)."""
    scene = textured_plane_scene(scale=2.0)
    scene.render.resolution_x = scene.render.resolution_y = 16
    img = bpy.data.images["grid"]
    # The middle of the image, on the plane (the white world is around it).
    first = render(scene, 'TESSERA', samples=4, bounces=0)[6:10, 6:10, :3].reshape(-1, 3).mean(axis=0)
    assert first[1] > 0.05 and first[2] > 0.05, first  # the colour grid has every hue
    img.pixels.foreach_set(np.tile(np.array([1.0, 0.0, 0.0, 1.0], dtype=np.float32), img.size[0] * img.size[1]))
    img.update()
    red = render(scene, 'TESSERA', samples=4, bounces=0)[6:10, 6:10, :3].reshape(-1, 3).mean(axis=0)
    assert red[0] > 0.2 and red[1] < 1e-3 and red[2] < 1e-3, (first, red)


@pytest.mark.parametrize("roughness", [0.0, 0.2, 0.5, 1.0])
@pytest.mark.parametrize("metallic", [0.0, 1.0])
def test_principled_roughness_ladder_matches_cycles(roughness, metallic):
    """Principled v1 on Blender 3.x, v2 (layered, Multiscatter GGX by default) on 4.x."""
    scene = empty_scene()
    add_plane(20.0, material=principled("Floor", (0.5, 0.5, 0.5), Specular=0.0, Roughness=1.0))
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.8, location=(0, 0, 0.8), segments=64, ring_count=32)
    bpy.ops.object.shade_smooth()
    bpy.context.object.data.materials.append(
        principled("Ball", (0.9, 0.6, 0.3), Metallic=metallic, Roughness=roughness, Specular=0.5))
    add_camera(scene, location=(0, -4.0, 1.6), rotation=(np.radians(80), 0, 0), lens=45)
    set_world(scene, (0.8, 0.9, 1.0), 1.0)
    bpy.ops.object.light_add(type='AREA', location=(1.5, -1.0, 3.0))
    bpy.context.object.data.energy = 300.0
    bpy.context.object.data.size = 1.0
    scene.render.resolution_x = scene.render.resolution_y = 96
    ours = render(scene, 'TESSERA', samples=128, bounces=4)
    ref = render(scene, 'CYCLES', samples=128, bounces=4)
    c = compare(ours, ref)
    print(roughness, metallic, {k: np.round(v, 4) for k, v in c.items()})
    assert np.all(np.isfinite(ours))
    assert np.all(c["mean_rel_diff"] < 0.02), c
    assert c["rel_rmse"] < 0.05, c


# ---------------------------------------------------------------- shader nodes beyond one Principled BSDF
#
# Each scene is rendered by Tessera and by Cycles in the test (same size,
# samples and bounces, transparent bounces too) and compared as the issue
# asks: mean per channel within 2%, and after downsampling by 8 a relative
# RMSE under 5% and no block off by more than 15%.

def _check(name, ours, ref, mean=0.02, rmse=0.05, block=0.15):
    """compare() and, stricter than its worst_block at these sizes, the worst
    pixel of the 1/8-downsampled images (an 8x8 block), relative to the
    reference block (at least a tenth of the image mean)."""
    c = compare(ours, ref)
    dt, dr = downsample(ours, 8), downsample(ref, 8)
    c["worst_block8"] = float(np.max(np.abs(dt - dr).mean(axis=-1) /
                                     np.maximum(dr.mean(axis=-1), 0.1 * dr.mean())))
    print(name, {k: np.round(v, 4) for k, v in c.items()})
    assert np.all(np.isfinite(ours)), f"{name}: Tessera wrote NaN or Inf pixels"
    assert np.all(c["mean_rel_diff"] < mean), (name, c)
    assert c["rel_rmse"] < rmse, (name, c)
    assert c["worst_block"] < block and c["worst_block8"] < block, (name, c)
    return c


def _both(scene, samples, bounces=4, size=96):
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.tessera.max_transparent_bounces = max(bounces, 1)  # as helpers.render sets Cycles'
    ours = render(scene, 'TESSERA', samples=samples, bounces=bounces)
    ref = render(scene, 'CYCLES', samples=samples, bounces=bounces)
    return ours, ref


def _shader_material(name, build):
    """A material whose Surface is what build(nodes, links) returns (an output socket)."""
    m = with_nodes(bpy.data.materials.new(name))
    nodes, links = m.node_tree.nodes, m.node_tree.links
    for n in list(nodes):
        if n.type != 'OUTPUT_MATERIAL':
            nodes.remove(n)
    out = next(n for n in nodes if n.type == 'OUTPUT_MATERIAL')
    links.new(build(nodes, links), out.inputs['Surface'])
    return m


def _bsdf(nodes, kind, **inputs):
    n = nodes.new(kind)
    for k, v in inputs.items():
        if k == 'distribution':
            n.distribution = v
        else:
            n.inputs[k].default_value = (*v, 1.0) if isinstance(v, tuple) else v
    return n


def _ball_scene(make_material, light=True):
    """A smooth sphere with the material make_material() returns on a grey floor before a red wall, under a
    pale world and an area light."""
    scene = empty_scene()
    material = make_material()
    add_plane(20.0, material=principled("Floor", (0.5, 0.5, 0.5), Specular=0.0, Roughness=1.0))
    add_plane(20.0, location=(0, 3.0, 0), rotation=(np.radians(90), 0, 0),
              material=principled("Wall", (0.7, 0.15, 0.1), Specular=0.0, Roughness=1.0))
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.8, location=(0, 0, 0.8), segments=64, ring_count=32)
    bpy.ops.object.shade_smooth()
    bpy.context.object.data.materials.append(material)
    add_camera(scene, location=(0, -4.0, 1.6), rotation=(np.radians(80), 0, 0), lens=45)
    set_world(scene, (0.8, 0.9, 1.0), 1.0)
    if light:
        bpy.ops.object.light_add(type='AREA', location=(1.5, -1.0, 3.0))
        bpy.context.object.data.energy = 300.0
        bpy.context.object.data.size = 1.0
    return scene


def _mix_material(fac=0.3):
    def build(nodes, links):
        d = _bsdf(nodes, 'ShaderNodeBsdfDiffuse', Color=(0.8, 0.3, 0.2))
        g = _bsdf(nodes, 'ShaderNodeBsdfGlossy', Color=(0.9, 0.9, 0.9), Roughness=0.3, distribution='GGX')
        mix = nodes.new('ShaderNodeMixShader')
        mix.inputs['Fac'].default_value = fac
        links.new(d.outputs[0], mix.inputs[1])
        links.new(g.outputs[0], mix.inputs[2])
        return mix.outputs[0]
    return _shader_material("MixDiffuseGlossy", build)


def test_mix_shader_matches_cycles():
    scene = _ball_scene(lambda: _mix_material(0.3))
    _check("mix 0.3", *_both(scene, 256))


def test_add_shader_matches_cycles():
    def build(nodes, links):
        d = _bsdf(nodes, 'ShaderNodeBsdfDiffuse', Color=(0.2, 0.4, 0.6), Roughness=0.5)
        g = _bsdf(nodes, 'ShaderNodeBsdfGlossy', Color=(0.5, 0.4, 0.3), Roughness=0.2, distribution='GGX')
        add = nodes.new('ShaderNodeAddShader')
        links.new(d.outputs[0], add.inputs[0])
        links.new(g.outputs[0], add.inputs[1])
        return add.outputs[0]
    scene = _ball_scene(lambda: _shader_material("AddDiffuseGlossy", build))
    _check("add", *_both(scene, 256))


@pytest.mark.parametrize("roughness", [0.0, 0.2, 0.5, 1.0])
def test_glossy_roughness_ladder_matches_cycles(roughness):
    def build(nodes, links):
        return _bsdf(nodes, 'ShaderNodeBsdfGlossy', Color=(0.9, 0.6, 0.3), Roughness=roughness,
                     distribution='GGX').outputs[0]
    scene = _ball_scene(lambda: _shader_material("Glossy", build))
    _check(f"glossy r={roughness}", *_both(scene, 256))


needs_cycles4 = pytest.mark.skipif(bpy.app.version < (4, 0, 0), reason=(
    "Multiscatter GGX is modelled as Cycles 4.x's energy compensation; Cycles 3.x's random-walk "
    "multiscatter GGX is not modelled (Tessera warns and renders single scattering there)"))


@needs_cycles4
@pytest.mark.parametrize("kind", ['ShaderNodeBsdfGlossy', 'ShaderNodeBsdfGlass'])
def test_multiscatter_ggx_white_furnace(kind):
    """A white rough Multiscatter GGX ball in a uniform white world, nothing
    else: it reflects (and refracts) all the light, so it disappears into the
    world, in Cycles and in Tessera (single-scattering GGX at this roughness
    keeps about half of it)."""
    def build(nodes, links):
        return _bsdf(nodes, kind, Color=(1.0, 1.0, 1.0), Roughness=1.0, distribution='MULTI_GGX').outputs[0]
    scene = empty_scene()
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=64, ring_count=32)
    bpy.ops.object.shade_smooth()
    bpy.context.object.data.materials.append(_shader_material("Furnace", build))
    add_camera(scene, location=(0, -4.0, 0), rotation=(np.radians(90), 0, 0), lens=50)
    set_world(scene, (1.0, 1.0, 1.0), 1.0)
    ours, ref = _both(scene, 64, bounces=16, size=48)
    ball = downsample(ours, 8)[1:-1, 1:-1], downsample(ref, 8)[1:-1, 1:-1]
    print(kind, "ball mean (ours, Cycles)", float(ball[0].mean()), float(ball[1].mean()))
    assert abs(float(ball[1].mean()) - 1.0) < 0.03, "Cycles' furnace is not white: the scene is not what the test means"
    assert abs(float(ball[0].mean()) - 1.0) < 0.03, ball[0]
    _check(f"furnace {kind}", ours, ref)


@needs_cycles4
@pytest.mark.parametrize("roughness", [0.5, 1.0])
def test_multiscatter_glossy_matches_cycles(roughness):
    def build(nodes, links):
        return _bsdf(nodes, 'ShaderNodeBsdfGlossy', Color=(0.9, 0.6, 0.3), Roughness=roughness,
                     distribution='MULTI_GGX').outputs[0]
    scene = _ball_scene(lambda: _shader_material("MultiGlossy", build))
    _check(f"multiscatter glossy r={roughness}", *_both(scene, 256))


@pytest.mark.parametrize("ior", [1.0, 1.1, 1.45, 2.0, 2.5])
def test_glass_ior_ladder_matches_cycles(ior):
    def build(nodes, links):
        return _bsdf(nodes, 'ShaderNodeBsdfGlass', Color=(0.9, 0.95, 1.0), Roughness=0.0, IOR=ior,
                     distribution='GGX').outputs[0]
    # World light only: sharp caustics of the area light through the ball are
    # too noisy for both engines at a few seconds per render.
    scene = _ball_scene(lambda: _shader_material("Glass", build), light=False)
    _check(f"glass ior={ior}", *_both(scene, 256, bounces=8))


def _see_through_scene(make_material, size=2.0):
    """A plane with the material make_material() returns between the camera and a coloured diffuse wall, lit
    from the camera's side."""
    scene = empty_scene()
    material = make_material()
    add_plane(20.0, location=(0, 2.0, 0), rotation=(np.radians(90), 0, 0),
              material=principled("Wall", (0.2, 0.6, 0.3), Specular=0.0, Roughness=1.0))
    add_plane(size, location=(0, 0.5, 0), rotation=(np.radians(90), 0, 0), material=material)
    add_camera(scene, location=(0, -4.0, 0), rotation=(np.radians(90), 0, 0), lens=50)
    set_world(scene, (0.3, 0.3, 0.3), 1.0)
    bpy.ops.object.light_add(type='AREA', location=(0.8, -2.0, 1.5), rotation=(np.radians(70), 0, 0))
    bpy.context.object.data.energy = 400.0
    bpy.context.object.data.size = 0.5
    return scene


def test_transparent_plane_matches_cycles():
    def build(nodes, links):
        t = _bsdf(nodes, 'ShaderNodeBsdfTransparent', Color=(0.9, 0.6, 0.3))
        d = _bsdf(nodes, 'ShaderNodeBsdfDiffuse', Color=(0.8, 0.8, 0.8))
        mix = nodes.new('ShaderNodeMixShader')
        mix.inputs['Fac'].default_value = 0.25  # a quarter diffuse: visible, and casting a tinted shadow
        links.new(t.outputs[0], mix.inputs[1])
        links.new(d.outputs[0], mix.inputs[2])
        return mix.outputs[0]
    scene = _see_through_scene(lambda: _shader_material("Tinted", build))
    _check("transparent", *_both(scene, 128))


@pytest.mark.parametrize("emission", [0.0, 2.0])
def test_principled_alpha_matches_cycles(emission):
    # Emission is mixed with the rest: it scales with alpha too.
    scene = _see_through_scene(lambda: principled("HalfAlpha", (0.9, 0.9, 0.2), Roughness=0.5, Alpha=0.5,
                                                  Emission=(0.5, 0.2, 0.1, 1.0), **{"Emission Strength": emission}))
    _check(f"alpha 0.5 emission {emission}", *_both(scene, 128))


def cutout_material():
    """Principled with an image's alpha as Alpha: opaque stripes and holes (a leaf cut-out)."""
    img = bpy.data.images.new("cutout", 32, 32, alpha=True)
    px = np.ones((32, 32, 4), dtype=np.float32)
    px[..., 3] = ((np.arange(32)[None, :] // 4) % 2).astype(np.float32)  # 4-texel vertical stripes
    img.pixels.foreach_set(px.ravel())
    m = principled("Cutout", (0.9, 0.8, 0.3), Roughness=0.5)
    nodes, links = m.node_tree.nodes, m.node_tree.links
    tex = nodes.new('ShaderNodeTexImage')
    tex.image = img
    tex.interpolation = 'Closest'
    links.new(tex.outputs['Alpha'], nodes["Principled BSDF"].inputs['Alpha'])
    return m


def test_alpha_cutout_texture_matches_cycles():
    scene = _see_through_scene(cutout_material, size=2.5)
    ours, ref = _both(scene, 256)
    _check("alpha cut-out", ours, ref)
    # Per texel, not the average: the stripes show, as in Cycles (the columns
    # through the plane alternate between plane colour and wall).
    row = ours[ours.shape[0] // 2, :, :3].mean(axis=-1)
    ref_row = ref[ref.shape[0] // 2, :, :3].mean(axis=-1)
    assert np.std(row) > 0.5 * np.std(ref_row) > 0.0, (np.std(row), np.std(ref_row))


def test_mix_factor_from_a_texture_is_named_in_a_warning():
    from tessera import engine

    def build(nodes, links):
        d = _bsdf(nodes, 'ShaderNodeBsdfDiffuse', Color=(0.8, 0.3, 0.2))
        g = _bsdf(nodes, 'ShaderNodeBsdfGlossy', Color=(0.9, 0.9, 0.9), Roughness=0.3)
        m = nodes.new('ShaderNodeMixShader')
        fresnel = nodes.new('ShaderNodeFresnel')
        links.new(fresnel.outputs[0], m.inputs['Fac'])
        links.new(d.outputs[0], m.inputs[1])
        links.new(g.outputs[0], m.inputs[2])
        return m.outputs[0]
    scene = _ball_scene(lambda: _shader_material("FresnelMix", build))
    scene.render.resolution_x = scene.render.resolution_y = 16
    render(scene, 'TESSERA', samples=1, bounces=0)
    warnings = " ".join(engine.last_render_stats.get("warnings", []))
    assert "FresnelMix" in warnings and "Mix Shader" in warnings and "varies over the surface" in warnings, warnings
    # The factor is Fresnel's average over viewing directions, not 0 (pure diffuse): 0.084 at the
    # Fresnel node's default IOR 1.45 (Blender 3.x), 0.092 at 1.5 (4.x); the standard values of
    # 2 int_0^1 F(mu) mu dmu for a dielectric of those IORs.
    expected = {1.45: "(0.084)", 1.5: "(0.092)"}[round(_fresnel_default_ior(), 2)]
    assert "varies with the viewing angle" in warnings and expected in warnings, (expected, warnings)


def _fresnel_default_ior():
    """The IOR a new Fresnel node starts with in this Blender."""
    tree = bpy.data.node_groups.new("probe", 'ShaderNodeTree')
    try:
        return tree.nodes.new('ShaderNodeFresnel').inputs['IOR'].default_value
    finally:
        bpy.data.node_groups.remove(tree)


def test_every_closure_follows_the_running_blenders_cycles():
    """Each closure of a mix carries the shading model of the Blender that
    exports it (a Principled BSDF in a Mix Shader was once left on Cycles
    3.x's model on 4.x: 3.5% too bright in the alpha test), and the versions
    map to the Cycles that changed the closures."""
    from tessera.export import materials

    def build(nodes, links):
        t = _bsdf(nodes, 'ShaderNodeBsdfTransparent')
        p = nodes.new('ShaderNodeBsdfPrincipled')
        d = _bsdf(nodes, 'ShaderNodeBsdfDiffuse', Color=(0.8, 0.3, 0.2))
        mix, mix2 = nodes.new('ShaderNodeMixShader'), nodes.new('ShaderNodeMixShader')
        links.new(t.outputs[0], mix.inputs[1])
        links.new(p.outputs[0], mix.inputs[2])
        links.new(mix.outputs[0], mix2.inputs[1])
        links.new(d.outputs[0], mix2.inputs[2])
        return mix2.outputs[0]
    empty_scene()

    class Report:
        def warn(self, key, message):
            pass
    params = materials.material_params(_shader_material("Mixed", build), Report())
    kinds = [params["kind"]] + [c["kind"] for c in params["closures"]]
    models = [params["model"]] + [c["model"] for c in params["closures"]]
    assert sorted(kinds) == ["DIFFUSE", "PRINCIPLED", "TRANSPARENT"], kinds
    expected = "CYCLES_3" if bpy.app.version < (4, 0, 0) else "CYCLES_4_3" if bpy.app.version >= (4, 3, 0) else "CYCLES_4"
    assert models == [expected] * 3, models
    assert [materials.shading_model(v) for v in ((3, 4, 1), (4, 2, 3), (4, 5, 0), (5, 0, 1))] == \
        ["CYCLES_3", "CYCLES_4", "CYCLES_4_3", "CYCLES_4_3"]


def test_image_texture_on_a_diffuse_bsdf_matches_cycles():
    """Per-texel textures reach the first textured closure of any kind (here a Diffuse BSDF in a mix)."""
    scene = empty_scene()

    def build(nodes, links):
        img = bpy.data.images.new("grid", 64, 64)
        img.generated_type = 'COLOR_GRID'
        tex = nodes.new('ShaderNodeTexImage')
        tex.image = img
        tex.interpolation = 'Closest'
        d = nodes.new('ShaderNodeBsdfDiffuse')
        links.new(tex.outputs['Color'], d.inputs['Color'])
        g = _bsdf(nodes, 'ShaderNodeBsdfGlossy', Color=(1.0, 1.0, 1.0), Roughness=0.4, distribution='GGX')
        mix = nodes.new('ShaderNodeMixShader')
        mix.inputs['Fac'].default_value = 0.2
        links.new(d.outputs[0], mix.inputs[1])
        links.new(g.outputs[0], mix.inputs[2])
        return mix.outputs[0]
    add_plane(2.0, material=_shader_material("TexturedDiffuse", build))
    add_camera(scene, location=(0, 0, 3.0), lens=40)
    set_world(scene, (1.0, 1.0, 1.0), 1.0)
    ours, ref = _both(scene, 64, bounces=1)
    _check("textured diffuse", ours, ref)
