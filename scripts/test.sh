#!/usr/bin/env bash
# Runs every test: native (GoogleTest under CTest), Python (pytest on the
# module, no Blender) and Blender (pytest inside a headless `blender -b`, once
# per Blender found). Sets the machine up first if needed (scripts/setup.sh).
# Extra arguments go to the Blender pytest run (e.g. -k cornell).
set -uo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh || { echo "tessera test: set-up failed" >&2; exit 1; }

failed=()
step() {
  local name=$1; shift
  echo "=== $name"
  if "$@"; then echo "=== $name: ok"; else echo "=== $name: FAILED"; failed+=("$name"); fi
}

step "native tests (ctest)" ctest --test-dir build --output-on-failure -j"$(nproc)"
step "python tests (pytest)" /usr/bin/python3 -m pytest tests/python -q -p no:cacheprovider
# TESSERA_BLENDERS: Blender binaries and/or Pythons with the bpy module (scripts/setup_bpy.sh),
# e.g. TESSERA_BLENDERS="blender $(scripts/setup_bpy.sh 4.5.*)". Default: Debian's blender only.
BLENDERS=${TESSERA_BLENDERS:-blender}
ran=()
for b in $BLENDERS; do
  if [[ $(basename "$b") == python* ]]; then
    version="bpy $("$b" -c 'import bpy; print(bpy.app.version_string)' 2>/dev/null | tail -n 1)"
    step "blender tests on $version" "$b" tests/blender/run.py -q "$@"
  else
    version=$("$b" --version 2>/dev/null | head -n 1)
    step "blender tests on $version" "$b" -b --factory-startup --python tests/blender/run.py -- -q "$@"
  fi
  ran+=("$version")
done
echo "tessera test: Blender suites ran on: $(IFS=,; echo "${ran[*]}")"

echo
if ((${#failed[@]})); then
  echo "tessera test: FAILED: ${failed[*]}"
  exit 1
fi
echo "tessera test: all suites passed"
