"""The module's material and camera arguments for closure lists, alpha and
depth of field (core: tests/native/test_materials.cpp)."""

import numpy as np
import pytest

import _core as core


def quad_scene(material_kwargs, camera_kwargs=None, w=16, h=16):
    s = core.Scene()
    p = np.array([[-10, -10, 0], [10, -10, 0], [10, 10, 0], [-10, 10, 0]], np.float32)
    i = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    s.add_instance(s.add_mesh(p, i), np.eye(4, dtype=np.float32), [s.add_material(**material_kwargs)])
    s.set_world_color([0.8, 0.6, 0.4])
    cam = np.eye(4, dtype=np.float32)
    cam[2, 3] = 3.0
    s.set_camera(type="PERSP", matrix=cam, left=-0.5, right=0.5, bottom=-0.5, top=0.5, clip_start=0.01,
                 clip_end=100.0, width=w, height=h, **(camera_kwargs or {}))
    s.commit()
    return s


def render(s, samples=4, threads=0):
    opt = core.RenderOptions()
    opt.samples = samples
    opt.threads = threads
    session = core.Session(s, opt)
    session.render()
    return session.pixels()


def test_transparent_closure_tints_the_world():
    s = quad_scene(dict(base_color=[0.5, 0.25, 1.0], kind="TRANSPARENT"))
    px = render(s)
    assert np.allclose(px[..., :3], [0.4, 0.15, 0.4], atol=1e-5)


def test_mixed_closures_and_alpha():
    # Black diffuse at weight 0.4 plus a transparent closure 0.6 of colour (1, 0.5, 0.5): 0.6 x tint x world.
    s = quad_scene(dict(base_color=[0, 0, 0], kind="DIFFUSE", weight=0.4,
                        closures=[dict(kind="TRANSPARENT", weight=0.6, base_color=[1.0, 0.5, 0.5])]))
    assert np.allclose(render(s)[..., :3], [0.48, 0.18, 0.12], atol=1e-5)
    # Principled alpha 0.25 on a black surface: 0.75 of the world.
    s = quad_scene(dict(base_color=[0, 0, 0], specular=0.0, alpha=0.25))
    assert np.allclose(render(s)[..., :3], [0.6, 0.45, 0.3], atol=1e-5)


def test_bad_closures_say_what_is_wrong():
    with pytest.raises(ValueError, match="unknown closure kind 'VELVET'"):
        quad_scene(dict(base_color=[1, 1, 1], kind="VELVET"))
    with pytest.raises(ValueError, match="unknown closure parameter 'colour'"):
        quad_scene(dict(base_color=[1, 1, 1], closures=[dict(kind="GLOSSY", colour=[1, 1, 1])]))
    with pytest.raises(ValueError, match="at most 8 closures"):
        quad_scene(dict(base_color=[1, 1, 1], closures=[dict(kind="DIFFUSE", weight=0.1)] * 8))


def test_depth_of_field_arguments():
    material = dict(base_color=[0.5, 0.5, 0.5])
    pinhole = render(quad_scene(material, w=24, h=16), samples=8)
    lens = dict(aperture_radius=0.2, focus_distance=1.0, blades=6, blades_rotation=0.3, aperture_ratio=1.2)
    a = render(quad_scene(material, lens, w=24, h=16), samples=8, threads=1)
    b = render(quad_scene(material, lens, w=24, h=16), samples=8, threads=0)
    assert np.array_equal(a, b)  # independent of the thread count
    assert not np.array_equal(a, pinhole)
    assert np.all(np.isfinite(a))
