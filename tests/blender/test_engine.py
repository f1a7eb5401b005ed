"""The engine's contract with Blender: failures reach the report (so that
`blender -b` exits non-zero), and sizes are Blender's."""

import bpy
import pytest

from helpers import render
from scenes import add_camera, add_plane, empty_scene, principled, set_world


def small_scene():
    scene = empty_scene()
    add_plane(2.0, material=principled("M"))
    add_camera(scene)
    set_world(scene, (0.5, 0.5, 0.5))
    return scene


def test_an_unexpected_exception_becomes_an_error_report(monkeypatch):
    # Regression: an exception escaping RenderEngine.render made Blender save a
    # black frame and exit 0.
    import tessera.export

    def broken(*args, **kwargs):
        raise ValueError("simulated failure")

    monkeypatch.setattr(tessera.export, "export_scene", broken)
    scene = small_scene()
    with pytest.raises(RuntimeError, match="Tessera failed to render: ValueError: simulated failure"):
        render(scene, 'TESSERA', samples=1, bounces=0)


def test_render_size_is_blenders():
    # Regression: 29% of 100 px gave 28 px (float rounding), Blender makes 29.
    scene = small_scene()
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 100, 60, 29
    from tessera.engine import render_size
    assert render_size(scene) == (29, 17)
    # The core renders exactly the result Blender allocates (the render would
    # fail with a size mismatch otherwise).
    img = render(scene, 'TESSERA', samples=1, bounces=0)
    assert img.shape[:2] == (17, 29)
