#!/usr/bin/env bash
# Opt-in: installs Blender as a Python module (the `bpy` wheel from PyPI, about
# 370 MB) into a venv, for running the Blender test suite on a newer Blender:
#   scripts/setup_bpy.sh [VERSION]            # default 4.5.* (LTS); e.g. 5.0.*
#   TESSERA_BLENDERS="blender $(scripts/setup_bpy.sh)" scripts/test.sh
# Prints the venv's python (the last line). Needs a Python matching the wheel
# (bpy 4.5 and 5.0 are cp311: Debian 12's /usr/bin/python3) and the core built
# for it (scripts/build.sh builds for /usr/bin/python3).
set -euo pipefail
version=${1:-4.5.*}
PYTHON=${TESSERA_BPY_PYTHON:-/usr/bin/python3}
venv=${TESSERA_BPY_VENV:-$HOME/.cache/tessera/bpy-${version//[*]/x}}
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import bpy, pytest" 2>/dev/null; then
  "$PYTHON" -m venv "$venv" >&2
  "$venv/bin/pip" install -q "bpy==$version" pytest >&2
fi
"$venv/bin/python" -c "import bpy; print('tessera setup_bpy: bpy', bpy.app.version_string)" >&2
echo "$venv/bin/python"
