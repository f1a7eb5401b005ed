"""The Properties editor as a Tessera user sees it: which panels Blender would
draw for the TESSERA engine, found the way Blender finds them (every registered
Panel of the Properties editor for the tab, polled with the tab's context),
and that drawing them works."""

from types import SimpleNamespace

import bpy
import pytest

from scenes import add_camera, empty_scene


class TabContext:
    """The context the Properties editor gives a panel's poll and draw: the
    named members, None for any other (as bpy.context has no `mesh` when the
    active object is a light)."""

    def __init__(self, **members):
        self.__dict__.update(members)

    def __getattr__(self, name):
        return None


def registered_panels():
    seen, todo = [], list(bpy.types.Panel.__subclasses__())
    while todo:
        cls = todo.pop()
        todo.extend(cls.__subclasses__())
        if cls not in seen and getattr(cls, "is_registered", False):
            seen.append(cls)
    return seen


def shown_panels(tab, context):
    """(class name, label) of the panels Blender shows in the Properties tab
    `tab` (bl_context) for this context: those whose poll passes (no poll:
    always), children only when their parent is shown."""
    candidates = {cls.bl_idname if hasattr(cls, "bl_idname") else cls.__name__: cls
                  for cls in registered_panels()
                  if getattr(cls, "bl_space_type", "") == 'PROPERTIES'
                  and getattr(cls, "bl_context", "") == tab}
    shown = {}

    def visible(name):
        if name in shown:
            return shown[name]
        cls = candidates.get(name)
        ok = cls is not None
        if ok and getattr(cls, "bl_parent_id", ""):
            ok = visible(cls.bl_parent_id)
        if ok and hasattr(cls, "poll"):
            ok = bool(cls.poll(context))
        shown[name] = ok
        return ok

    return sorted((name, getattr(candidates[name], "bl_label", "")) for name in candidates if visible(name))


def light_context(light_type):
    scene = empty_scene()
    scene.render.engine = 'TESSERA'
    add_camera(scene)
    data = bpy.data.lights.new("L", light_type)
    obj = bpy.data.objects.new("L", data)
    scene.collection.objects.link(obj)
    return TabContext(engine='TESSERA', scene=scene, object=obj, light=data, active_object=obj,
                      view_layer=bpy.context.view_layer)


@pytest.mark.parametrize("light_type", ['POINT', 'SPOT', 'SUN', 'AREA'])
def test_light_tab_has_one_light_panel_and_nothing_eevee(light_type):
    # Regression: Blender's DATA_PT_light (the type row only) and EEVEE's
    # DATA_PT_EEVEE_light (the type row again, and on 3.x EEVEE's
    # Diffuse/Specular/Volume factors) were both enabled for Tessera.
    panels = shown_panels("data", light_context(light_type))
    top = [(n, label) for n, label in panels if not getattr(getattr(bpy.types, n, None), "bl_parent_id", "")]
    assert [label for _, label in top].count("Light") == 1, panels
    assert not [n for n, _ in panels if "EEVEE" in n], panels
    if light_type in ('SPOT', 'AREA'):
        assert "Beam Shape" in [label for _, label in panels], panels
    else:
        assert "Beam Shape" not in [label for _, label in panels], panels


def light_panel_properties(light_type, shape='SQUARE'):
    """The Light properties that Tessera's light panels draw, by calling their
    draw() with a recording layout."""
    context = light_context(light_type)
    if shape:
        context.light.shape = shape
    drawn = []

    class Layout:
        def __getattr__(self, name):
            return lambda *args, **kwargs: Layout()

        def __setattr__(self, name, value):
            pass

        def prop(self, data, prop, **kwargs):
            drawn.append(prop)

        def row(self, *args, **kwargs):
            return Layout()

    names = [n for n, _ in shown_panels("data", context) if n.startswith("TESSERA")]
    assert names, "no Tessera light panel"
    for name in names:
        panel = getattr(bpy.types, name)
        panel.draw(SimpleNamespace(layout=Layout(), bl_space_type='PROPERTIES'), context)
    return drawn


@pytest.mark.parametrize("light_type,shape,expected", [
    ('POINT', None, {"type", "color", "energy", "shadow_soft_size"}),
    ('SPOT', None, {"type", "color", "energy", "shadow_soft_size", "spot_size", "spot_blend"}),
    ('SUN', None, {"type", "color", "energy", "angle"}),
    ('AREA', 'RECTANGLE', {"type", "color", "energy", "shape", "size", "size_y", "spread"}),
])
def test_light_panel_shows_what_tessera_reads(light_type, shape, expected):
    drawn = set(light_panel_properties(light_type, shape))
    assert expected <= drawn, drawn
    light_rna = bpy.types.Light.bl_rna.properties
    if "normalize" in light_rna:  # Blender 4.x
        assert "normalize" in drawn and "exposure" in drawn, drawn
        if light_type in ('POINT', 'SPOT'):
            assert "use_soft_falloff" in drawn, drawn
    # Settings Tessera does not read: EEVEE's factors, shadows and distance.
    ignored = {"diffuse_factor", "specular_factor", "volume_factor", "transmission_factor", "use_shadow",
               "cutoff_distance", "use_custom_distance"}
    assert not drawn & ignored, drawn & ignored


def test_render_tab_has_tesseras_panels():
    scene = empty_scene()
    scene.render.engine = 'TESSERA'
    panels = shown_panels("render", TabContext(engine='TESSERA', scene=scene))
    labels = [label for _, label in panels]
    for label in ("Sampling", "Light Paths", "Film", "Performance", "Color Management"):
        assert label in labels, labels
    assert not [label for label in labels if label in ("Bloom", "Ambient Occlusion")], labels
    # The Film panel is Tessera's (Transparent), not EEVEE's (filter size, overscan).
    assert [name for name, label in panels if label == "Film"] == ["TESSERA_PT_film"], panels
