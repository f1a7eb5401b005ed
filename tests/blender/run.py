"""Runs the Blender test suite inside `blender -b`:

    blender -b --factory-startup --python tests/blender/run.py -- [pytest args]

Registers the add-on from this checkout (no installed preferences needed) and
exits with pytest's status, so a failure makes Blender exit non-zero."""

import os
import sys

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "addon"))
sys.path.insert(0, HERE)

import pytest  # noqa: E402  (Debian's python3-pytest, visible to Blender's Python)

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
print(f"Blender tests on Blender {bpy.app.version_string}, Python {sys.version.split()[0]}")
code = pytest.main([HERE, "-p", "no:cacheprovider", *argv])
sys.stdout.flush()
os._exit(int(code))
