#!/usr/bin/env bash
# Builds the native core and places the Python module inside addon/tessera.
# The module is built for the Python that Blender embeds (Debian's Blender
# 3.4.1 embeds the system Python 3.11).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
PYTHON=${TESSERA_PYTHON:-/usr/bin/python3}
cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DPYTHON_EXECUTABLE="$PYTHON" ${CMAKE_ARGS:-} >/dev/null
cmake --build "$BUILD_DIR" -j"$(nproc)"
# Copy then rename: a Blender that has the old module loaded keeps its file.
for so in "$BUILD_DIR"/_core*.so; do
  cp -f "$so" "addon/tessera/.$(basename "$so").tmp"
  mv -f "addon/tessera/.$(basename "$so").tmp" "addon/tessera/$(basename "$so")"
done
echo "tessera build: $(ls addon/tessera/_core*.so)"
