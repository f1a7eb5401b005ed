"""Render-farm use (issue 7): a frame rendered as four region renders in
separate `blender -b` processes and stitched is bit-identical to the full
render with the same seed; an animation shared by two processes through
Blender's placeholder / no-overwrite options renders every frame exactly
once; failed renders give a non-zero exit status."""

import os
import re
import shutil
import subprocess

import bpy
import numpy as np
import pytest

from helpers import SCENES, blender_render_frame, load_image

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
ADDON = os.path.join(ROOT, "addon")
REGION = os.path.join(ROOT, "scripts", "farm_region_render.py")
ANIMATION = os.path.join(ROOT, "scripts", "farm_animation.sh")

pytestmark = pytest.mark.skipif(
    not bpy.app.binary_path, reason="farm tests start `blender -b` processes; the bpy module has no Blender binary")


def blender_env():
    return dict(os.environ, BLENDER=bpy.app.binary_path)


def python():
    # The driver needs the standard library and numpy. Not sys.executable: a pyenv shim
    # would put its Python first on PATH, and Blender started from it finds that Python's
    # site-packages (no numpy) instead of the system's.
    return "/usr/bin/python3" if os.path.exists("/usr/bin/python3") else shutil.which("python3")



def region_render(tmp_path, name, *args, env=None):
    out = str(tmp_path / name)
    proc = subprocess.run([python(), REGION, os.path.join(SCENES, "cornell_mcguire.blend"), out,
                           "--size", "37x29", "--samples", "3", "--seed", "7", "--addon", ADDON, *args],
                          env=env or blender_env(), capture_output=True, text=True, timeout=600)
    print(proc.stdout, proc.stderr)
    return proc, out


def test_four_region_renders_stitch_to_the_full_render(tmp_path):
    # 37x29: odd sizes, so the tiles are unequal and Blender's truncation of the border counts.
    full_proc, full = region_render(tmp_path, "full.exr", "--tiles", "1x1")
    assert full_proc.returncode == 0
    tiled_proc, tiled = region_render(tmp_path, "tiled.exr", "--tiles", "2x2")
    assert tiled_proc.returncode == 0
    assert tiled_proc.stdout.count("done (") == 4
    a, b = load_image(full), load_image(tiled)
    assert a.shape == b.shape == (29, 37, 4)
    assert a[..., :3].mean() > 0.01, "the reference render is black"
    assert np.array_equal(a, b), f"stitched differs from the full render in {np.count_nonzero(a != b)} values"


def broken_installed_addon_env(tmp_path):
    """Blender's user folders with Tessera enabled in the preferences, its add-on link then left dangling (a
    checkout moved or deleted since it was installed): every `blender -b` that reads the preferences prints a
    traceback for it."""
    scripts, config = tmp_path / "user_scripts", tmp_path / "user_config"
    (scripts / "addons").mkdir(parents=True)
    config.mkdir()
    link = scripts / "addons" / "tessera"
    link.symlink_to(os.path.join(ADDON, "tessera"))
    env = dict(blender_env(), BLENDER_USER_SCRIPTS=str(scripts), BLENDER_USER_CONFIG=str(config))
    subprocess.run([bpy.app.binary_path, "-b", "--python-expr",
                    "import bpy; bpy.ops.preferences.addon_enable(module='tessera'); bpy.ops.wm.save_userpref()"],
                   env=env, capture_output=True, text=True, timeout=300, check=True)
    assert (config / "userpref.blend").exists()
    link.unlink()
    link.symlink_to(str(tmp_path / "moved_checkout" / "tessera"))
    return env


def test_addon_option_renders_with_that_addon_whatever_blender_has_installed(tmp_path):
    """--addon DIR renders with DIR's add-on: the farm's Blenders skip the user preferences (--factory-startup),
    so an add-on installed there (another Tessera, or a dangling link to one) neither replaces it nor fails the
    tiles with its traceback."""
    env = broken_installed_addon_env(tmp_path)
    proc, out = region_render(tmp_path, "tiled.exr", "--tiles", "2x1", env=env)
    assert proc.returncode == 0, proc.stderr
    assert load_image(out)[..., :3].mean() > 0.01


def test_uncropped_region_renders_stitch_to_the_full_render(tmp_path):
    # Flamenco-style tiles: border without crop, full-size images with the region filled.
    full_proc, full = region_render(tmp_path, "full.exr", "--tiles", "1x1")
    tiled_proc, tiled = region_render(tmp_path, "tiled.exr", "--tiles", "2x2", "--no-crop", "--jobs", "2")
    assert full_proc.returncode == 0 and tiled_proc.returncode == 0
    assert np.array_equal(load_image(full), load_image(tiled))


def test_failed_render_exits_non_zero(tmp_path):
    """A scene Tessera cannot render (no camera) makes `blender -b` and the farm script exit non-zero."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_cube_add()
    blend = str(tmp_path / "no_camera.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    proc = blender_render_frame(blend, tmp_path)
    assert proc.returncode != 0, proc.stdout
    assert not list(tmp_path.glob("f_*.png")), "a failed render wrote an image"
    farm = subprocess.run([python(), REGION, blend, str(tmp_path / "out.exr"), "--size", "8x8", "--addon", ADDON],
                          env=blender_env(), capture_output=True, text=True, timeout=600)
    assert farm.returncode == 1, farm.stdout + farm.stderr
    assert "FAILED" in farm.stderr and not os.path.exists(tmp_path / "out.exr")


def test_two_processes_share_an_animation_each_frame_once(tmp_path):
    out = tmp_path / "frames"
    proc = subprocess.run([ANIMATION, os.path.join(SCENES, "bunny_glass.blend"), str(out), "-s", "1", "-e", "8",
                           "--size", "24x18", "--samples", "4", "--addon", ADDON],
                          env=blender_env(), capture_output=True, text=True, timeout=900)
    print(proc.stdout, proc.stderr)
    assert proc.returncode == 0
    files = sorted(p.name for p in out.iterdir() if p.is_file())
    assert files == [f"frame_{f:04d}.png" for f in range(1, 9)]
    assert all((out / f).stat().st_size > 0 for f in files)
    saved = []
    for log in sorted((out / ".farm_logs").glob("worker_*.log")):
        saved += re.findall(r"^Saved: '.*frame_(\d{4})\.png'", log.read_text(), flags=re.M)
    # Every frame saved by exactly one of the two processes (none rendered twice).
    assert sorted(saved) == [f"{f:04d}" for f in range(1, 9)], saved
