#!/usr/bin/env bash
# Set up MuBlE on a fresh Debian/Ubuntu machine: system libraries for headless OpenGL (MuJoCo) and bpy,
# a Python 3.11 virtual environment in .venv, and the project with its test extras (editable).
set -euo pipefail
cd "$(dirname "$0")/.."

# Headless GL (EGL through Mesa, OSMesa as the fallback) and the X libraries bpy links against.
APT_PACKAGES=(libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri libosmesa6 libglu1-mesa libx11-6 libxrender1 libxi6
              libxxf86vm1 libxfixes3 libxkbcommon0 libsm6)
missing=()
for p in "${APT_PACKAGES[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
if [ ${#missing[@]} -gt 0 ]; then
  echo "installing system packages: ${missing[*]}"
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

PYTHON=${PYTHON:-python3.11}
command -v "$PYTHON" >/dev/null || { echo "MuBlE needs Python 3.11 (bpy 5 requires exactly 3.11): set PYTHON=" >&2; exit 1; }
[ -x .venv/bin/python ] || "$PYTHON" -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -e ".[test]"
echo "MuBlE installed in $(pwd)/.venv"
