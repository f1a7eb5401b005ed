"""Loads the native core. If it cannot load (another platform or Python, a
missing library), the add-on still registers and says exactly why."""

import sys

try:
    from . import _core as native  # noqa: F401
    load_error = None
except ImportError as e:  # pragma: no cover - exercised by a Blender test that hides the module
    native = None
    load_error = (
        f"Tessera's native core could not be loaded into this Blender "
        f"(Python {sys.version_info.major}.{sys.version_info.minor}, {sys.platform}): {e}. "
        f"Install the Tessera build made for this Blender version and platform "
        f"(see README.md, 'Install'), or rebuild it with scripts/setup.sh."
    )


def ray_mask(settings, flags, default=True):
    """The core's ray-kind mask (visibility.h) from Blender's visibility
    checkboxes: flags pairs each property of `settings` with a kind's name
    (RAY_CAMERA, RAY_DIFFUSE, ...); a missing property counts as `default`."""
    mask = 0
    for attr, kind in flags:
        if getattr(settings, attr, default):
            mask |= getattr(native, kind)
    return mask
