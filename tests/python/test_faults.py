"""Faults at the module level (issue 6): cancel at random moments returns
promptly, 0 samples, and renders of degenerate input stay finite."""

import random
import time

import numpy as np

import _core as core


def scene(w=64, h=64):
    s = core.Scene()
    p = np.array([[-10, -10, 0], [10, -10, 0], [10, 10, 0], [-10, 10, 0]], np.float32)
    i = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    m = s.add_mesh(p, i)
    s.add_instance(m, np.eye(4, dtype=np.float32), [s.add_material(base_color=[0.5, 0.5, 0.5])])
    s.set_world_color([1.0, 1.0, 1.0])
    cam = np.eye(4, dtype=np.float32)
    cam[2, 3] = 3.0
    s.set_camera(type="PERSP", matrix=cam, left=-0.5, right=0.5, bottom=-0.5, top=0.5,
                 clip_start=0.01, clip_end=100.0, width=w, height=h)
    s.commit()
    return s


def test_cancel_at_random_moments_returns_promptly():
    s = scene(128, 128)
    rng = random.Random(6)
    worst = 0.0
    for _ in range(15):
        opt = core.RenderOptions()
        opt.samples = 100000
        session = core.Session(s, opt)
        session.start()
        time.sleep(rng.uniform(0.0, 0.15))
        t0 = time.perf_counter()
        session.cancel()
        assert session.wait(10.0)
        worst = max(worst, time.perf_counter() - t0)
        st = session.stats()
        assert st["cancelled"] and st["samples_done"] < 100000
        assert np.all(np.isfinite(session.pixels()))
    print(f"worst cancel latency {worst * 1000:.1f} ms over 15 random cancels")
    assert worst < 1.0


def test_cancel_before_start_and_destroy_while_running():
    s = scene()
    opt = core.RenderOptions()
    opt.samples = 100000
    session = core.Session(s, opt)
    session.cancel()
    session.start()
    assert session.wait(5.0)
    running = core.Session(s, opt)
    running.start()
    t0 = time.perf_counter()
    del running  # the destructor cancels and joins
    assert time.perf_counter() - t0 < 2.0


def test_zero_and_negative_samples_give_a_black_finite_image():
    for n in (0, -5):
        opt = core.RenderOptions()
        opt.samples = n
        session = core.Session(scene(8, 8), opt)
        session.render()
        px = session.pixels()
        assert px.shape == (8, 8, 4) and np.all(np.isfinite(px))
        assert session.stats()["samples_done"] == 0


def test_degenerate_materials_and_images_stay_finite():
    s = core.Scene()
    p = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0], [0, 0, 0], [0, 0, 0], [2, 0, 0]], np.float32)
    i = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 4, 4], [0, 1, 1]], np.uint32)  # + zero-area and sliver
    normals = np.zeros((15, 3), np.float32)  # zero-length shading normals
    mesh = s.add_mesh(p, i, None, normals)
    mats = []
    for rough in (0.0, 1e-7, 1e-3, 1.0, 100.0, -1.0):
        for ior in (1.0, 1.0001, 1.5, 4.0, 0.0, 1e6):
            for em in (0.0, 1e-6, 1e6):
                mats.append(s.add_material(base_color=[1, 1, 1], roughness=rough, ior=ior, transmission=0.5,
                                           metallic=0.3, emission_front=[em] * 3, emission_back=[em] * 3))
    for k, m in enumerate(mats[::6]):
        xf = np.eye(4, dtype=np.float32)
        xf[0, 3], xf[2, 3] = (k % 10) * 0.3 - 1.5, -0.01 * k
        s.add_instance(mesh, xf, [m])
    s.set_world_color([1.0, 1.0, 1.0])
    for w, h in ((1, 1), (2048, 1), (1, 512), (16, 16)):
        cam = np.eye(4, dtype=np.float32)
        cam[2, 3] = 3.0
        s.set_camera(type="PERSP", matrix=cam, left=-1, right=1, bottom=-1, top=1, clip_start=0.01,
                     clip_end=100.0, width=w, height=h)
        s.commit()
        opt = core.RenderOptions()
        opt.samples = 4
        session = core.Session(s, opt)
        session.render()
        px = session.pixels()
        assert px.shape == (h, w, 4)
        assert np.all(np.isfinite(px)), (w, h)


def test_scene_far_from_the_origin_can_be_changed_after_commit():
    """commit() moves a scene seen from 1e5 away into camera-relative space;
    a camera, instance or light given afterwards in world space lands in the
    same place, and ray queries stay in world space."""
    far = np.array([1e5, -1e5, 1e5], np.float32)

    def build():
        s = core.Scene()
        p = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
        m = s.add_mesh(p, np.array([[0, 1, 2], [0, 2, 3]], np.uint32))
        xf = np.eye(4, dtype=np.float32)
        xf[:3, 3] = far
        s.add_instance(m, xf, [s.add_material(base_color=[0.5, 0.5, 0.5])])
        s.add_light(type="POINT", position=(far + [0, 0, 2]).tolist(), radiance=[10, 10, 10])
        return s, m, xf

    def camera(s):
        cam = np.eye(4, dtype=np.float32)
        cam[:3, 3] = far + [0, 0, 3]
        s.set_camera(type="PERSP", matrix=cam, left=-0.5, right=0.5, bottom=-0.5, top=0.5,
                     clip_start=0.01, clip_end=100.0, width=16, height=16)

    def image(s):
        opt = core.RenderOptions()
        opt.samples = 4
        session = core.Session(s, opt)
        session.render()
        return session.pixels()

    s, m, xf = build()
    camera(s)
    s.commit()
    first = image(s)
    assert first[..., :3].mean() > 0.1
    hit = s.intersect((far + [0.25, 0.25, 3]).tolist(), [0, 0, -1])
    assert hit is not None and abs(hit[0] - 3.0) < 1e-3
    assert np.allclose(hit[3], far + [0.25, 0.25, 0], atol=0.02)
    # The same camera again, and a second commit: the same image.
    camera(s)
    s.commit()
    assert np.array_equal(image(s), first)
    # An instance added afterwards in world space is where it should be.
    xf2 = xf.copy()
    xf2[0, 3] += 10.0
    s.add_instance(m, xf2, [0])
    s.commit()
    assert s.intersect((far + [10, 0, 3]).tolist(), [0, 0, -1]) is not None
