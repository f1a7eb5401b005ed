"""Instancing: 1000 collection instances of a ~80k-triangle mesh are exported
and stored as one mesh (memory ~ one mesh plus the instance table), and
geometry-nodes instances (Instance on Points) and linked duplicates map to one
mesh too. Checked through tessera.engine.last_render_stats; renders are tiny."""

import bpy
import numpy as np

from helpers import render, set_size


def _empty_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    cam_data = bpy.data.cameras.new("Cam")
    cam = bpy.data.objects.new("Cam", cam_data)
    scene.collection.objects.link(cam)
    cam.location = (30.0, -40.0, 30.0)
    cam.rotation_euler = (0.95, 0.0, 0.65)
    scene.camera = cam
    light = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    scene.collection.objects.link(light)
    set_size(scene, 16, 16)
    return scene


def _high_poly_mesh(name="Src"):
    """An icosphere of 81,920 triangles (20 * 4^6; Blender counts the base icosahedron as 1)."""
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=7, radius=0.8)
    obj = bpy.context.active_object
    obj.name = name
    return obj


def _stats(scene):
    from tessera import engine
    render(scene, 'TESSERA', samples=1, bounces=1)
    return dict(engine.last_render_stats)


def _one_mesh_bytes():
    scene = _empty_scene()
    src = _high_poly_mesh()
    stats = _stats(scene)
    assert stats["meshes"] == 1 and stats["instances"] == 1
    return stats, len(src.data.polygons)


def test_thousand_collection_instances_store_one_mesh():
    one, faces = _one_mesh_bytes()
    tris = one["triangles"]
    assert tris == faces == 81920

    scene = _empty_scene()
    coll = bpy.data.collections.new("Source")
    scene.collection.children.link(coll)
    src = _high_poly_mesh()
    for c in list(src.users_collection):
        c.objects.unlink(src)
    coll.objects.link(src)
    # The source collection is not rendered itself, only through its instances.
    bpy.context.view_layer.layer_collection.children["Source"].exclude = True
    for i in range(1000):
        e = bpy.data.objects.new(f"Inst{i}", None)
        e.instance_type = 'COLLECTION'
        e.instance_collection = coll
        e.location = (2.0 * (i % 10), 2.0 * ((i // 10) % 10), 2.0 * (i // 100))
        e.rotation_euler = (0.1 * i, 0.0, 0.05 * i)
        scene.collection.objects.link(e)
    stats = _stats(scene)
    assert stats["instances"] == 1000
    assert stats["meshes"] == 1
    assert stats["triangles"] == tris
    assert stats["instanced_triangles"] == 1000 * tris
    # One mesh plus the instance table and TLAS: well under 2 copies of the mesh
    # (a flattened scene would need ~1000).
    extra = stats["memory_bytes"] - one["memory_bytes"]
    assert 0 <= extra < 1000 * 1024, stats
    assert stats["memory_bytes"] < 1.5 * one["memory_bytes"], stats
    for key in ("export_seconds", "blas_build_seconds", "tlas_build_seconds"):
        assert stats[key] >= 0.0
    print(f"\none mesh: {one['memory_bytes']} bytes, blas {one['blas_build_seconds']:.3f} s; "
          f"1000 instances: {stats['memory_bytes']} bytes, blas {stats['blas_build_seconds']:.3f} s, "
          f"tlas {stats['tlas_build_seconds']:.4f} s, export {stats['export_seconds']:.3f} s")


def test_linked_duplicates_share_one_mesh():
    scene = _empty_scene()
    src = _high_poly_mesh()
    for i in range(20):
        dup = bpy.data.objects.new(f"Dup{i}", src.data)  # linked duplicate (Alt+D)
        dup.location = (2.0 * (i + 1), 0.0, 0.0)
        scene.collection.objects.link(dup)
    stats = _stats(scene)
    assert stats["instances"] == 21
    assert stats["meshes"] == 1
    assert stats["triangles"] == 81920
    assert stats["instanced_triangles"] == 21 * 81920


def test_geometry_nodes_instance_on_points_share_one_mesh():
    scene = _empty_scene()
    src = _high_poly_mesh()
    src.hide_render = True  # only its instances are rendered
    bpy.ops.mesh.primitive_plane_add(size=10.0)
    carrier = bpy.context.active_object
    carrier.name = "Carrier"
    tree = bpy.data.node_groups.new("Scatter", 'GeometryNodeTree')
    if hasattr(tree, "interface"):  # Blender 4.0+
        tree.interface.new_socket("Geometry", in_out='INPUT', socket_type='NodeSocketGeometry')
        tree.interface.new_socket("Geometry", in_out='OUTPUT', socket_type='NodeSocketGeometry')
    else:
        tree.inputs.new('NodeSocketGeometry', "Geometry")
        tree.outputs.new('NodeSocketGeometry', "Geometry")
    n_in = tree.nodes.new('NodeGroupInput')
    n_out = tree.nodes.new('NodeGroupOutput')
    grid = tree.nodes.new('GeometryNodeMeshGrid')
    grid.inputs["Size X"].default_value = 10.0
    grid.inputs["Size Y"].default_value = 10.0
    grid.inputs["Vertices X"].default_value = 6
    grid.inputs["Vertices Y"].default_value = 5
    info = tree.nodes.new('GeometryNodeObjectInfo')
    info.inputs["Object"].default_value = src
    iop = tree.nodes.new('GeometryNodeInstanceOnPoints')
    tree.links.new(grid.outputs["Mesh"], iop.inputs["Points"])
    tree.links.new(info.outputs["Geometry"], iop.inputs["Instance"])
    tree.links.new(iop.outputs["Instances"], n_out.inputs[0])
    del n_in
    mod = carrier.modifiers.new("Scatter", 'NODES')
    mod.node_group = tree
    stats = _stats(scene)
    assert stats["instances"] == 30, stats
    assert stats["meshes"] == 1, stats
    assert stats["triangles"] == 81920
    assert stats["instanced_triangles"] == 30 * 81920
