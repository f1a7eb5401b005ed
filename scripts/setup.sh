#!/usr/bin/env bash
# Sets up a fresh Debian 12 machine for Tessera: installs Blender and the build
# dependencies from Debian's packages, builds the native core against the
# Python that Blender embeds, installs and enables the add-on for this user.
# Safe to run again; it only redoes what is needed.
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(blender cmake g++ make pybind11-dev libglm-dev libtbb-dev python3-dev python3-venv python3-numpy python3-pytest
          googletest libgtest-dev clang libclang-rt-14-dev python3-matplotlib)
scripts/install_packages.sh "${PACKAGES[@]}"

scripts/build.sh
scripts/install_addon.sh
