# SPDX-License-Identifier: GPL-2.0-or-later
"""Tessera: a path-tracing render engine for Blender with a native C++ core."""

bl_info = {
    "name": "Tessera",
    "author": "Tessera developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Render > Render Engine > Tessera",
    "description": "Path-tracing render engine with a native C++ core",
    "category": "Render",
}

from . import engine, properties, ui  # noqa: E402

_modules = (properties, engine, ui)


def register():
    for m in _modules:
        m.register()


def unregister():
    for m in reversed(_modules):
        m.unregister()
