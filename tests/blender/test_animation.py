"""Animation and camera override (issue 7): objects that move between frames
render where they are in each frame of an animation render, and a camera
override (a sequencer scene strip's camera) replaces the scene's camera."""

import glob
import math
import os
import tempfile

import bpy
import numpy as np

from helpers import configure_engine, load_image
from scenes import add_camera, add_plane, empty_scene, principled, set_world


def emitter(name, color):
    # Black and without specular: it only emits (nothing of the other emitter is reflected).
    return principled(name, color=(0.0, 0.0, 0.0), Specular=0.0, Emission=(*color, 1.0),
                      **{"Emission Strength": 1.0})


def exr_output(scene, directory, name):
    r = scene.render
    r.image_settings.file_format = 'OPEN_EXR'
    r.image_settings.color_depth = '32'
    r.use_compositing = False
    r.filepath = os.path.join(directory, name)


def test_objects_move_between_the_frames_of_an_animation():
    # An emissive square, keyed to move 1 unit along x from frame 1 to frame 3,
    # seen from above by an orthographic camera 4 units wide at 64 px: 16 px a unit.
    scene = empty_scene()
    set_world(scene, (0.0, 0.0, 0.0))
    add_camera(scene, location=(0, 0, 5), kind='ORTHO', ortho_scale=4.0)
    bpy.context.preferences.edit.keyframe_new_interpolation_type = 'LINEAR'
    square = add_plane(0.5, location=(-0.5, 0, 0), material=emitter("Moving", (1.0, 1.0, 1.0)))
    square.keyframe_insert("location", frame=1)
    square.location.x = 0.5
    square.keyframe_insert("location", frame=3)
    scene.frame_start, scene.frame_end = 1, 3
    configure_engine(scene, 'TESSERA', samples=4, bounces=1)
    out = tempfile.mkdtemp(prefix="tessera_anim_")
    exr_output(scene, out, "frame_")
    bpy.ops.render.render(animation=True)
    files = sorted(glob.glob(os.path.join(out, "frame_*.exr")))
    assert [os.path.basename(f) for f in files] == ["frame_0001.exr", "frame_0002.exr", "frame_0003.exr"]
    centres = []
    for f in files:
        lum = load_image(f)[..., :3].mean(axis=-1)
        ys, xs = np.nonzero(lum > 0.5)
        assert len(xs) > 0, f"{f}: the square is not in the image"
        centres.append(xs.mean())
    # Frame 1 at x = -0.5, frame 2 at 0, frame 3 at 0.5: 8 px per frame.
    steps = np.diff(centres)
    assert np.allclose(steps, 8.0, atol=0.75), f"square centres (px) {centres}"
    # The scene is left at the frame Blender left it; the still render of
    # frame 2 equals the animation's frame 2 bit for bit (same seed, same pixels).
    scene.frame_set(2)
    exr_output(scene, out, "still_2.exr")
    bpy.ops.render.render(write_still=True)
    assert np.array_equal(load_image(os.path.join(out, "still_2.exr")), load_image(files[1]))


def test_camera_override_of_a_sequencer_scene_strip():
    # Camera A looks down -z at a red emitter, camera B up +z at a blue one.
    # The scene's camera is A; a sequencer strip shows the scene through B.
    scene = empty_scene()
    set_world(scene, (0.0, 0.0, 0.0))
    add_plane(20.0, location=(0, 0, -3), material=emitter("Red", (1.0, 0.0, 0.0)))
    add_plane(20.0, location=(0, 0, 3), material=emitter("Blue", (0.0, 0.0, 1.0)))
    cam_b = add_camera(scene, location=(0, 0, 0), rotation=(math.pi, 0, 0))
    cam_a = add_camera(scene, location=(0, 0, 0))
    assert scene.camera == cam_a
    configure_engine(scene, 'TESSERA', samples=4, bounces=1)
    out = tempfile.mkdtemp(prefix="tessera_override_")
    exr_output(scene, out, "scene.exr")
    bpy.ops.render.render(write_still=True)
    direct = load_image(os.path.join(out, "scene.exr"))[..., :3].mean(axis=(0, 1))
    assert direct[0] > 0.9 and direct[2] < 0.01, f"scene camera: mean RGB {direct}"

    edit = bpy.data.scenes.new("Edit")
    edit.render.resolution_x = edit.render.resolution_y = 64
    edit.render.resolution_percentage = 100
    edit.view_settings.view_transform = 'Standard'
    edit.frame_start = edit.frame_end = edit.frame_current = 1
    edit.sequence_editor_create()
    # Blender 5.0 renamed the editor's `sequences` to `strips`.
    editor = edit.sequence_editor
    strips = editor.strips if hasattr(editor, "strips") else editor.sequences
    strip = strips.new_scene("Shot", scene, 1, 1)
    strip.scene_camera = cam_b
    edit.render.use_sequencer = True
    exr_output(edit, out, "edit.exr")
    bpy.ops.render.render(write_still=True, scene=edit.name)
    through_b = load_image(os.path.join(out, "edit.exr"))[..., :3].mean(axis=(0, 1))
    assert through_b[2] > 0.9 and through_b[0] < 0.01, f"strip camera override: mean RGB {through_b}"
