"""Renders the shared scenes with Tessera and with Cycles at the same size,
samples and bounces, and compares them."""

import numpy as np
import pytest

from helpers import compare, enlarge_small_lights, open_scene, remove_duplicate_faces, render, set_size


# Issue 2 asked for 5% on the two Cornell boxes; issue 3's 2% holds (0.5% and 0.2%).
@pytest.mark.parametrize("name", ["cornell_mcguire.blend", "cbox_mitsuba.blend"])
def test_mean_matches_cycles(name):
    scene = open_scene(name)
    # McGuire's box repeats two faces; Cycles 3.4 shades them with z-fighting
    # stripes (about 6% of this image's mean). Both engines get clean data here;
    # test_duplicate_faces_render_as_one_surface covers Tessera on the original.
    remove_duplicate_faces(scene)
    set_size(scene, 96)
    ours = render(scene, 'TESSERA', samples=256, bounces=8)
    ref = render(scene, 'CYCLES', samples=256, bounces=8)
    assert np.all(np.isfinite(ours)), "Tessera wrote NaN or Inf pixels"
    c = compare(ours, ref)
    print(name, {k: np.round(v, 4) for k, v in c.items()})
    assert np.all(c["mean_rel_diff"] < 0.02), f"{name}: mean per channel {c['mean_test']} vs Cycles {c['mean_ref']}"


def test_duplicate_faces_render_as_one_surface():
    """Coincident duplicate faces (McGuire's box has two) give the same image
    as the deduplicated mesh: no z-fighting, no self-shadowing."""
    scene = open_scene("cornell_mcguire.blend")
    set_size(scene, 64)
    original = render(scene, 'TESSERA', samples=64, bounces=4)
    assert remove_duplicate_faces(scene) == 2
    clean = render(scene, 'TESSERA', samples=64, bounces=4)
    c = compare(original, clean)
    assert np.all(c["mean_rel_diff"] < 0.01), c
    assert c["worst_block"] < 0.05, c


# Issue 3, at the level each scene holds today (docs/compare has the full,
# converged table on Blender 3.4 and 4.5). modern_hall was 9% dark until
# emitters on mirrored instances were light-sampled from the side they are
# shaded with. These hold on Cycles 4.x too, since Tessera models Principled v2
# and Multiscatter GGX (Blender 4.5 and 5.0 measured).
@pytest.mark.parametrize("name,bound", [("veach_mis.blend", 0.03), ("modern_hall.blend", 0.02)])
def test_more_shared_scenes_match_cycles(name, bound):
    scene = open_scene(name)
    set_size(scene, 96)
    ours = render(scene, 'TESSERA', samples=128, bounces=8)
    ref = render(scene, 'CYCLES', samples=128, bounces=8)
    assert np.all(np.isfinite(ours)), "Tessera wrote NaN or Inf pixels"
    c = compare(ours, ref)
    print(name, {k: np.round(v, 4) for k, v in c.items()})
    assert np.all(c["mean_rel_diff"] < bound), f"{name}: mean per channel {c['mean_test']} vs Cycles {c['mean_ref']}"


def test_bunny_glass_matches_cycles():
    """The glass bunny with its two lights enlarged (enlarge_small_lights): the
    caustics of the file's 1 cm spot and 20 x 10 cm area light through the glass
    are heavy-tailed noise at test samples (the mean moved by -5% to +2% between
    runs on 4.5 at 128 spp, in both directions), while the converged file agrees
    (docs/compare). Larger lights keep the glass (Principled transmission, smooth,
    IOR 1.5), the floor, the HDRI world and both light models, converged."""
    scene = open_scene("bunny_glass.blend")
    assert enlarge_small_lights(scene) == 2
    set_size(scene, 96)
    ours = render(scene, 'TESSERA', samples=256, bounces=8)
    ref = render(scene, 'CYCLES', samples=256, bounces=8)
    assert np.all(np.isfinite(ours)), "Tessera wrote NaN or Inf pixels"
    c = compare(ours, ref)
    print("bunny_glass.blend, lights enlarged", {k: np.round(v, 4) for k, v in c.items()})
    assert np.all(c["mean_rel_diff"] < 0.02), f"mean per channel {c['mean_test']} vs Cycles {c['mean_ref']}"
