"""Speed/accuracy controls through Blender: presets, time limit, clamping,
adaptive sampling (deterministic across thread counts), error target and the
render log. Small renders; correctness only, never wall-clock."""

import numpy as np
import pytest

from helpers import open_scene, render, set_size


@pytest.fixture
def cornell():
    scene = open_scene("cornell_mcguire.blend")
    set_size(scene, 48)
    return scene


def stats():
    from tessera import engine
    return engine.last_render_stats


def test_presets_set_the_controls(cornell):
    t = cornell.tessera
    t.preset = 'PREVIEW'
    assert t.adaptive_threshold > 0 and t.max_bounces == 4 and t.samples == 32
    t.preset = 'REFERENCE'
    assert t.adaptive_threshold == 0 and t.clamp_indirect == 0 and t.samples >= 4096
    assert t.diffuse_texture_blur == 0 and t.light_threshold == 0
    import bpy
    bpy.ops.tessera.apply_preset(preset='PRODUCTION')
    assert t.max_diffuse_bounces == 4 and t.clamp_indirect == 10
    assert t.diffuse_texture_blur == pytest.approx(1 / 64)
    assert t.light_threshold == pytest.approx(0.01)  # Cycles' default


def test_light_threshold_reaches_the_core_and_keeps_the_mean(cornell):
    # McGuire's box: above 0.3 many light samples fall under the threshold.
    cornell.tessera.estimate_error = False
    cornell.tessera.light_threshold = 0.0
    every = render(cornell, 'TESSERA', samples=64)[..., :3]
    rays_every = stats()["rays"]
    cornell.tessera.light_threshold = 1.0
    some = render(cornell, 'TESSERA', samples=64)[..., :3]
    print(f"light threshold 1: rays {stats()['rays'] / rays_every:.3f} of all, mean {some.mean():.5f} against {every.mean():.5f}")
    assert stats()["rays"] < 0.97 * rays_every
    assert not np.array_equal(every, some)
    assert some.mean() == pytest.approx(every.mean(), rel=0.02)


def test_caustic_light_paths_reach_the_core_and_keep_the_mean():
    # bunny_glass: the glass bunny's caustic of the 1 cm spot light. With
    # caustic light paths the caustic is light-traced (and the path tracer
    # drops the same paths); without, path tracing alone. The image means
    # agree within the noise of path tracing's caustic, and the light paths
    # show in the render log.
    bunny = open_scene("bunny_glass.blend")
    set_size(bunny, 64)
    bunny.tessera.estimate_error = False
    means = {}
    for paths in (0.0, 0.25):
        bunny.tessera.caustic_light_paths = paths
        means[paths] = np.mean([render(bunny, 'TESSERA', samples=64, seed=s)[..., :3].mean() for s in range(4)])
        assert (stats()["light_paths"] > 0) == (paths > 0)
    assert stats()["light_paths"] == round(0.25 * 64 * 64 * 48)
    print(f"bunny_glass means: path tracing {means[0.0]:.5f}, with caustic light paths {means[0.25]:.5f}")
    assert means[0.25] == pytest.approx(means[0.0], rel=0.02)


def test_diffuse_texture_blur_reaches_the_textures_and_keeps_the_mean():
    # modern_hall's wood, tiles and wallpaper are image textures: with the blur
    # the paths after a diffuse bounce read their blurred levels, so the image
    # changes, and its mean does not beyond the noise of 16 samples.
    hall = open_scene("modern_hall.blend")
    set_size(hall, 64)
    images = []
    for blur in (0.0, 1 / 64):
        hall.tessera.diffuse_texture_blur = blur
        images.append(render(hall, 'TESSERA', samples=16, seed=3)[..., :3])
    sharp, blurred = images
    assert not np.array_equal(sharp, blurred)
    assert blurred.mean() == pytest.approx(sharp.mean(), rel=0.01)


def test_time_limit_stops_the_render(cornell):
    cornell.tessera.time_limit = 0.5
    render(cornell, 'TESSERA', samples=1_000_000)
    s = stats()
    assert s["stop_reason"] == "time limit"
    assert 0 < s["samples"] < 1_000_000


def test_clamping_bounds_pixel_values(cornell):
    img = render(cornell, 'TESSERA', samples=16, bounces=0)
    assert img[..., :3].max() > 2.0  # the emitter is seen directly
    cornell.tessera.clamp_direct = 0.5
    cornell.tessera.clamp_indirect = 0.25
    img = render(cornell, 'TESSERA', samples=16, bounces=0)
    # Per sample: emission and light sampling at the first hit, emission at the second.
    assert img[..., :3].max() <= 2 * 0.5 + 0.25 + 1e-5


def test_adaptive_sampling_stops_early_and_is_deterministic(cornell):
    t = cornell.tessera
    t.adaptive_threshold, t.adaptive_min_samples = 0.1, 16
    a = render(cornell, 'TESSERA', samples=256, threads=1)
    sa = dict(stats())
    b = render(cornell, 'TESSERA', samples=256, threads=2)
    sb = dict(stats())
    assert np.array_equal(a, b)
    assert sa["pixel_samples"] == sb["pixel_samples"]
    assert 16 <= sa["mean_samples"] < 256 * 0.75


def test_error_target_is_reached(cornell):
    cornell.tessera.error_target = 0.2
    render(cornell, 'TESSERA', samples=100_000)
    s = stats()
    assert s["stop_reason"] == "error target"
    assert s["estimated_error"] < 0.2


def test_emitter_antialiasing_traces_more_camera_rays_on_the_lights_edge_only(cornell):
    # The light is seen directly: its edge pixels trace extra camera rays for
    # their emission when the setting allows it, a few pixels' worth; the
    # image keeps its mean.
    cornell.tessera.estimate_error = False
    cornell.tessera.max_camera_rays = 1
    off = render(cornell, 'TESSERA', samples=16)
    rays_off = stats()["rays"]
    assert stats()["antialiased_pixels"] == 0
    cornell.tessera.max_camera_rays = 64
    on = render(cornell, 'TESSERA', samples=16)
    rays_on = stats()["rays"]
    pixels_on = stats()["antialiased_pixels"]
    assert rays_off < rays_on < 1.25 * rays_off
    assert 0 < pixels_on < 0.1 * 48 * 48
    assert abs(on[..., :3].mean() / off[..., :3].mean() - 1.0) < 0.05
