"""Runs the Blender test suite inside Blender, either the application or the
`bpy` module from PyPI (Blender 4.2+ as a Python module, scripts/setup_bpy.sh):

    blender -b --factory-startup --python tests/blender/run.py -- [pytest args]
    VENV/bin/python tests/blender/run.py [pytest args]

Registers the add-on from this checkout (no installed preferences needed) and
exits with pytest's status, so a failure makes Blender (or Python) exit non-zero."""

import os
import sys

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "addon"))
sys.path.insert(0, HERE)

# Blender's own Python sees Debian's python3-pytest; a bpy venv has its own pytest.
import pytest  # noqa: E402

if bpy.app.binary_path:  # the Blender application: our arguments follow "--"
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
else:  # the bpy module: plain Python arguments
    argv = sys.argv[1:]
    bpy.ops.wm.read_factory_settings(use_empty=True)
kind = "Blender" if bpy.app.binary_path else "bpy module"
print(f"Blender tests on {kind} {bpy.app.version_string}, Python {sys.version.split()[0]}")
code = pytest.main([HERE, "-p", "no:cacheprovider", *argv])
sys.stdout.flush()
os._exit(int(code))
