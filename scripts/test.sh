#!/usr/bin/env bash
# Runs every test: native (GoogleTest under CTest), Python (pytest on the
# module, no Blender) and Blender (pytest inside a headless `blender -b`, once
# per Blender found: Debian's and the bpy venvs of scripts/setup_bpy.sh). Sets the machine up first if needed (scripts/setup.sh).
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
# The Blenders: Debian's `blender` and every bpy venv that scripts/setup_bpy.sh made
# (~/.cache/tessera/bpy-*/bin/python, e.g. 4.5 LTS and 5.0); a fresh machine has only
# `blender`. TESSERA_BLENDERS overrides the list: Blender binaries and/or Pythons with the
# bpy module, e.g. TESSERA_BLENDERS="blender $(scripts/setup_bpy.sh 5.0.*)".
if [ -n "${TESSERA_BLENDERS:-}" ]; then
  read -ra BLENDERS <<<"$TESSERA_BLENDERS"
else
  BLENDERS=()
  command -v blender >/dev/null && BLENDERS+=(blender)
  for py in "$HOME"/.cache/tessera/bpy-*/bin/python; do
    [ -x "$py" ] && BLENDERS+=("$py")
  done
  if ! ((${#BLENDERS[@]})); then
    echo "=== blender tests: FAILED: no Blender found (no \`blender\` on PATH, no bpy venv under" \
         "~/.cache/tessera); run scripts/setup.sh, or set TESSERA_BLENDERS"
    failed+=("blender tests (no Blender)")
  fi
fi
ran=()
for b in "${BLENDERS[@]}"; do
  before=${#failed[@]}
  if [[ $(basename "$b") == python* ]]; then
    version=$("$b" -c 'import bpy; print(bpy.app.version_string)' 2>/dev/null | tail -n 1)
    if [ -z "$version" ]; then
      echo "=== blender tests on $b: FAILED: it does not import bpy; remake the venv with" \
           "scripts/setup_bpy.sh VERSION, or delete its folder to skip it"
      failed+=("blender tests on $b"); ran+=("$b (FAILED: no bpy)"); continue
    fi
    version="bpy $version"
    step "blender tests on $version" "$b" tests/blender/run.py -q "$@"
  else
    version=$("$b" --version 2>/dev/null | head -n 1)
    [ -n "$version" ] || version=$b
    step "blender tests on $version" "$b" -b --factory-startup --python tests/blender/run.py -- -q "$@"
  fi
  ((${#failed[@]} > before)) && ran+=("$version (FAILED)") || ran+=("$version (ok)")
done
echo "tessera test: Blender suites ran on: $(IFS=,; echo "${ran[*]:-none}" | sed 's/,/, /g')"

echo
if ((${#failed[@]})); then
  echo "tessera test: FAILED: ${failed[*]}"
  exit 1
fi
echo "tessera test: all suites passed"
