#!/usr/bin/env bash
# Renders the bundled demo scene headless with Tessera into out/demo_0001.png.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p out
blender -b demo/demo.blend -E TESSERA -o "$PWD/out/demo_" -F PNG -f 1
test -s out/demo_0001.png
echo "tessera demo: wrote $PWD/out/demo_0001.png"
