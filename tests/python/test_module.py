"""The native module used from plain Python (no Blender): buffers in, pixels
out, and clear errors on bad input."""

import numpy as np
import pytest

import _core as core


def quad(z=0.0, size=1.0):
    p = np.array([[-size, -size, z], [size, -size, z], [size, size, z], [-size, size, z]], np.float32)
    i = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    return p, i


def camera_looking_down(scene, w=16, h=16):
    m = np.eye(4, dtype=np.float32)
    m[2, 3] = 3.0  # at z = 3 looking down -z
    scene.set_camera(type="PERSP", matrix=m, left=-0.5, right=0.5, bottom=-0.5, top=0.5,
                     clip_start=0.01, clip_end=100.0, width=w, height=h)


def lit_scene():
    s = core.Scene()
    p, i = quad(size=10.0)  # fills the view
    white = s.add_material(base_color=[0.5, 0.5, 0.5], specular=0.0)
    mesh = s.add_mesh(p, i)
    s.add_instance(mesh, np.eye(4, dtype=np.float32), [white])
    s.set_world_color([1.0, 1.0, 1.0])
    camera_looking_down(s)
    s.commit()
    return s


def render(scene, **kw):
    opt = core.RenderOptions()
    for k, v in kw.items():
        setattr(opt, k, v)
    session = core.Session(scene, opt)
    session.render()
    return session.pixels(), session.stats()


def test_white_furnace_plane_under_uniform_sky():
    # A Lambertian-like plane of albedo 0.5 under a white sky, one bounce:
    # radiance = albedo * sky (the sky below the plane is hidden by nothing,
    # but the plane only sees the upper hemisphere).
    px, stats = render(lit_scene(), samples=256, max_bounces=1)
    assert px.shape == (16, 16, 4)
    assert np.all(np.isfinite(px))
    mean = px[..., :3].mean()
    assert 0.45 < mean < 0.6, mean  # principled diffuse is not exactly Lambert
    assert stats["samples_done"] == 256 and stats["rays"] > 0


def test_same_pixels_for_one_and_all_threads():
    s = lit_scene()
    a, _ = render(s, samples=8, threads=1)
    b, _ = render(s, samples=8, threads=0, tile_size=3)
    assert np.array_equal(a, b)


def test_background_only_scene_renders_the_world():
    s = core.Scene()
    s.set_world_color([0.25, 0.5, 1.0])
    camera_looking_down(s)
    s.commit()
    px, _ = render(s, samples=4)
    assert np.allclose(px[..., :3], [0.25, 0.5, 1.0])


def test_instances_share_one_mesh():
    s = core.Scene()
    p, i = quad(size=0.1)
    mesh = s.add_mesh(p, i)
    for k in range(100):
        m = np.eye(4, dtype=np.float32)
        m[0, 3] = k * 0.3
        s.add_instance(mesh, m, [])
    camera_looking_down(s)
    s.commit()
    assert s.num_meshes == 1 and s.num_instances == 100
    assert s.num_triangles == 2 and s.num_instanced_triangles == 200


def test_errors_say_what_is_wrong():
    s = core.Scene()
    with pytest.raises(ValueError, match="positions must have 3 values per row"):
        s.add_mesh(np.zeros((4, 2), np.float32), np.zeros((1, 3), np.uint32))
    p, i = quad()
    with pytest.raises(ValueError, match="one entry per triangle"):
        s.add_mesh(p, i, material_slots=np.zeros(5, np.uint32))
    with pytest.raises(IndexError, match="no mesh with index 7"):
        s.add_instance(7, np.eye(4, dtype=np.float32), [])
    with pytest.raises(ValueError, match="unknown light type 'LASER'"):
        s.add_light(type="LASER", position=[0, 0, 0])
    with pytest.raises(ValueError, match=r"diffuse_blur must be in \[0, 1\]"):
        s.add_texture(np.ones((4, 4, 4), np.float32), diffuse_blur=-0.5)
    with pytest.raises(ValueError, match="image size must be positive"):
        s.set_camera(type="PERSP", matrix=np.eye(4, dtype=np.float32), left=-1, right=1, bottom=-1, top=1,
                     clip_start=0.1, clip_end=10, width=0, height=10)


def test_nan_vertices_are_skipped_and_counted():
    s = core.Scene()
    p, i = quad()
    p[0, 0] = np.nan
    mesh = s.add_mesh(p, i)
    assert s.mesh_skipped_triangles(mesh) == 2  # vertex 0 is in both triangles


def test_cancel_returns_promptly():
    import time
    s = lit_scene()
    opt = core.RenderOptions()
    opt.samples = 1_000_000
    session = core.Session(s, opt)
    session.start()
    time.sleep(0.2)
    t0 = time.perf_counter()
    session.cancel()
    assert session.wait(5.0)
    assert time.perf_counter() - t0 < 1.0
    assert session.stats()["cancelled"]


def test_live_figures_are_taken_at_the_last_update():
    """While rendering, rays and samples change only at pass boundaries;
    update_seconds is when they did, so rays / update_seconds is the rate and
    remaining_seconds counts down from the progress then (the status line's
    rate sagged between updates when divided by the live elapsed time)."""
    import time
    scene = lit_scene()
    opt = core.RenderOptions()
    opt.samples = 1 << 14
    opt.time_limit = 1.0
    session = core.Session(scene, opt)
    session.start()
    seen = []
    while not session.wait(0.02):
        # update_seconds before elapsed_seconds: a pass that ends between the
        # two reads would otherwise give an update later than the elapsed time
        # read before it (CI saw exactly that once).
        u = session.update_seconds
        seen.append((session.elapsed_seconds, u, session.remaining_seconds))
    assert all(u <= e + 1e-9 for e, u, _ in seen)
    assert any(u > 0 for _, u, _ in seen)
    # Under a 1 s time limit the remaining time never exceeds what is left of it.
    assert all(r <= 1.0 - e + 0.05 for e, _, r in seen if r >= 0)
    assert session.update_seconds > 0 and session.remaining_seconds == 0.0
