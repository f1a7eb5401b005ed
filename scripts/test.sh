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
BLENDERS=${TESSERA_BLENDERS:-blender}
for b in $BLENDERS; do
  version=$("$b" --version 2>/dev/null | head -n 1)
  step "blender tests on $version" "$b" -b --factory-startup --python tests/blender/run.py -- -q "$@"
done

echo
if ((${#failed[@]})); then
  echo "tessera test: FAILED: ${failed[*]}"
  exit 1
fi
echo "tessera test: all suites passed"
