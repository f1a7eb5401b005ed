#!/usr/bin/env bash
# Installs the add-on for this user (a link to addon/tessera in Blender's user
# add-on folder) and enables it in the saved preferences, so that
# `blender -b FILE -E TESSERA ...` works.
set -euo pipefail
cd "$(dirname "$0")/.."
BLENDER=${BLENDER:-blender}
addons_dir=$("$BLENDER" -b --factory-startup --python-expr \
  "import bpy; print('ADDONS_DIR=' + bpy.utils.user_resource('SCRIPTS', path='addons', create=True))" 2>/dev/null |
  sed -n 's/^ADDONS_DIR=//p')
[ -n "$addons_dir" ] || { echo "tessera install: could not ask $BLENDER for its add-on folder" >&2; exit 1; }
mkdir -p "$addons_dir"
ln -sfn "$PWD/addon/tessera" "$addons_dir/tessera"
"$BLENDER" -b --python-expr "
import bpy, sys
bpy.ops.preferences.addon_enable(module='tessera')
bpy.ops.wm.save_userpref()
import tessera.core as c
if c.load_error: print(c.load_error); sys.exit(1)
print('TESSERA_ENABLED')
" 2>&1 | grep -q TESSERA_ENABLED || { echo "tessera install: enabling the add-on in $BLENDER failed" >&2; exit 1; }
echo "tessera install: add-on linked at $addons_dir/tessera and enabled"
