"""Small scenes the Blender tests build themselves."""

import math

import bpy


def empty_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.view_settings.view_transform = 'Standard'
    scene.render.resolution_x = scene.render.resolution_y = 64
    scene.render.resolution_percentage = 100
    return scene


def with_nodes(idblock):
    """A new material or world with its node tree: use_nodes before Blender 5.0; 5.0 always uses nodes
    (use_nodes is deprecated there and goes in 6.0), and new ones come with their default nodes."""
    if bpy.app.version < (5, 0, 0):
        idblock.use_nodes = True
    return idblock


def principled(name, color=(0.8, 0.8, 0.8), **inputs):
    m = with_nodes(bpy.data.materials.new(name))
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*color, 1.0)
    for k, v in inputs.items():
        # Blender 4.0 renamed Principled inputs; 3.x names are accepted here.
        k = {"Specular": "Specular IOR Level", "Transmission": "Transmission Weight",
             "Emission": "Emission Color"}.get(k, k) if k not in p.inputs else k
        p.inputs[k].default_value = v
    return m


def add_plane(size, location=(0, 0, 0), rotation=(0, 0, 0), material=None):
    bpy.ops.mesh.primitive_plane_add(size=size, location=location, rotation=rotation)
    obj = bpy.context.object
    if material:
        obj.data.materials.append(material)
    return obj


def add_camera(scene, location=(0, 0, 5), rotation=(0, 0, 0), lens=50.0, kind='PERSP', ortho_scale=4.0):
    bpy.ops.object.camera_add(location=location, rotation=rotation)
    cam = bpy.context.object
    cam.data.type = kind
    cam.data.lens = lens
    cam.data.ortho_scale = ortho_scale
    scene.camera = cam
    return cam


def set_world(scene, color=(0.0, 0.0, 0.0), strength=1.0):
    world = with_nodes(bpy.data.worlds.new("World"))
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*color, 1.0)
    bg.inputs["Strength"].default_value = strength
    scene.world = world
    return world


def floor_under_light(light_type, **light_props):
    """A white diffuse floor seen from above, lit by one light of the given type."""
    scene = empty_scene()
    add_plane(20, material=principled("Floor", (0.8, 0.8, 0.8), Specular=0.0, Roughness=1.0))
    add_camera(scene, location=(0, 0, 6), lens=35)
    set_world(scene)
    bpy.ops.object.light_add(type=light_type, location=(0.7, -0.4, 2.0), rotation=(math.radians(15), 0, 0))
    light = bpy.context.object
    for k, v in light_props.items():
        setattr(light.data, k, v)
    return scene
