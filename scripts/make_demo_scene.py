"""Builds demo/demo.blend, the scene the README's first command renders:
blender -b --factory-startup --python scripts/make_demo_scene.py

A small room with a subdivided Suzanne (modifier), a row of instanced
spheres (a collection instance), a glossy metal sphere, a glass sphere,
an area light, an emissive panel and a dim world."""

import math
import os

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "demo", "demo.blend")

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene


def material(name, color, metallic=0.0, roughness=0.5, specular=0.5, transmission=0.0, emission=None):
    m = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):  # 5.0 always uses nodes; use_nodes is deprecated there
        m.use_nodes = True
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*color, 1.0)
    p.inputs["Metallic"].default_value = metallic
    p.inputs["Roughness"].default_value = roughness
    p.inputs["Specular"].default_value = specular
    p.inputs["Transmission"].default_value = transmission
    if emission:
        p.inputs["Emission"].default_value = (*emission[0], 1.0)
        p.inputs["Emission Strength"].default_value = emission[1]
    return m


def add(obj, mat):
    obj.data.materials.append(mat)
    return obj


white = material("White", (0.8, 0.8, 0.8), roughness=0.8, specular=0.2)
red = material("Red", (0.7, 0.08, 0.06), roughness=0.8, specular=0.2)
blue = material("Blue", (0.08, 0.15, 0.6), roughness=0.8, specular=0.2)
gold = material("Gold", (1.0, 0.77, 0.34), metallic=1.0, roughness=0.25)
glass = material("Glass", (1.0, 1.0, 1.0), roughness=0.0, transmission=1.0)
clay = material("Clay", (0.8, 0.45, 0.3), roughness=0.5)
panel = material("Panel", (0.0, 0.0, 0.0), specular=0.0, emission=((1.0, 0.85, 0.6), 6.0))

# Room: floor, back wall and two side walls. The floor reaches past the
# camera (y = -7.5), so the bottom of the frame sees floor, not the world.
bpy.ops.mesh.primitive_plane_add(size=6, location=(0, -3, 0))
bpy.context.object.scale.y = 2.0  # y from -9 to 3
add(bpy.context.object, white)
bpy.ops.mesh.primitive_plane_add(size=6, location=(0, 3, 3), rotation=(math.pi / 2, 0, 0))
add(bpy.context.object, white)
bpy.ops.mesh.primitive_plane_add(size=6, location=(-3, 0, 3), rotation=(0, math.pi / 2, 0))
add(bpy.context.object, red)
bpy.ops.mesh.primitive_plane_add(size=6, location=(3, 0, 3), rotation=(0, math.pi / 2, 0))
add(bpy.context.object, blue)

# Suzanne, smooth, with a subdivision modifier.
bpy.ops.mesh.primitive_monkey_add(location=(0, 0.5, 1.0), rotation=(0, 0, math.radians(-20)))
suzanne = add(bpy.context.object, clay)
suzanne.modifiers.new("Subdivision", 'SUBSURF').levels = 2
suzanne.modifiers["Subdivision"].render_levels = 2
bpy.ops.object.shade_smooth()

# Metal and glass spheres.
bpy.ops.mesh.primitive_uv_sphere_add(radius=0.6, location=(-1.6, -0.3, 0.6), segments=48, ring_count=24)
add(bpy.context.object, gold)
bpy.ops.object.shade_smooth()
bpy.ops.mesh.primitive_uv_sphere_add(radius=0.6, location=(1.6, -0.4, 0.6), segments=48, ring_count=24)
add(bpy.context.object, glass)
bpy.ops.object.shade_smooth()

# A row of small spheres: one mesh, placed by collection instances.
pebbles = bpy.data.collections.new("Pebbles")
bpy.ops.mesh.primitive_ico_sphere_add(radius=0.15, subdivisions=3, location=(0, 0, 0))
pebble = add(bpy.context.object, white)
bpy.ops.object.shade_smooth()
for c in pebble.users_collection:
    c.objects.unlink(pebble)
pebbles.objects.link(pebble)
for i in range(9):
    inst = bpy.data.objects.new(f"Pebble.{i}", None)
    inst.instance_type = 'COLLECTION'
    inst.instance_collection = pebbles
    inst.location = (-2.0 + 0.5 * i, -1.6, 0.15)
    scene.collection.objects.link(inst)

# Lights: an area light and an emissive panel on the back wall.
bpy.ops.object.light_add(type='AREA', location=(0.5, -1.0, 4.5))
area = bpy.context.object
area.data.energy = 400.0
area.data.size = 1.5
bpy.ops.mesh.primitive_plane_add(size=1.0, location=(0, 2.98, 3.2), rotation=(math.pi / 2, 0, 0))
add(bpy.context.object, panel)

# World and camera.
world = bpy.data.worlds.new("World")
if bpy.app.version < (5, 0, 0):
    world.use_nodes = True
world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.05, 0.06, 0.08, 1.0)
scene.world = world
bpy.ops.object.camera_add(location=(0, -7.5, 2.2), rotation=(math.radians(82), 0, 0))
scene.camera = bpy.context.object
scene.camera.data.lens = 32

scene.render.resolution_x, scene.render.resolution_y = 640, 400
scene.render.engine = 'TESSERA' if hasattr(scene, "tessera") else scene.render.engine
scene.view_settings.view_transform = 'Standard'
os.makedirs(os.path.dirname(OUT), exist_ok=True)
bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(OUT), compress=True)
print(f"wrote {os.path.abspath(OUT)}")
