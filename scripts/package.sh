#!/usr/bin/env bash
# Packages the add-on with its compiled core (scripts/build.sh) into dist/:
#   tessera-VERSION-addon-linux-x64.zip      legacy add-on for Blender 3.x to 4.1 (and 4.2+ as
#                                            a legacy add-on): the folder tessera/ with bl_info
#   tessera-VERSION-extension-linux-x64.zip  Blender 4.2+ extension: blender_manifest.toml and
#                                            the package files at the zip's root
# Both carry every addon/tessera/_core.cpython-3XX-*.so present (one per Python the core was
# built for; see docs/PACKAGING.md). NO_CORE=1 leaves the core out (tests the error path).
set -euo pipefail
cd "$(dirname "$0")/.."
DIST=$(realpath -m "${DIST:-dist}")
[ "${NO_CORE:-0}" = 1 ] || compgen -G "addon/tessera/_core*.so" >/dev/null ||
  { echo "tessera package: no compiled core in addon/tessera; run scripts/build.sh first" >&2; exit 1; }
version=$(sed -n 's/^ *"version": *(\([0-9]*\), *\([0-9]*\), *\([0-9]*\)).*/\1.\2.\3/p' addon/tessera/__init__.py)
[ -n "$version" ] || { echo "tessera package: no version in bl_info" >&2; exit 1; }
stage=$(mktemp -d); trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage/tessera" "$DIST"
# Sources and cores only: no caches, no temporary copies of the core.
(cd addon && find tessera -name '*.py' -o -name 'blender_manifest.toml' -o -name '_core*.so') |
  grep -v __pycache__ | while read -r f; do
    if [ "${NO_CORE:-0}" = 1 ] && [[ $f == *.so ]]; then continue; fi
    mkdir -p "$stage/$(dirname "$f")"; cp "addon/$f" "$stage/$f"
  done
sed -i "s/^version = .*/version = \"$version\"/" "$stage/tessera/blender_manifest.toml"
suffix=""; [ "${NO_CORE:-0}" = 1 ] && suffix="-nocore"
legacy="$DIST/tessera-$version-addon-linux-x64$suffix.zip"
extension="$DIST/tessera-$version-extension-linux-x64$suffix.zip"
rm -f "$legacy" "$extension"
(cd "$stage" && zip -qr -X "$legacy" tessera)
(cd "$stage/tessera" && zip -qr -X "$extension" .)
echo "tessera package: $legacy"
echo "tessera package: $extension"
echo "tessera package: cores: $(cd "$stage/tessera" && ls _core*.so 2>/dev/null | tr '\n' ' ')"
