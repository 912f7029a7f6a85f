#!/usr/bin/env bash
# Set up MuBlE on a fresh Debian/Ubuntu machine: system libraries for headless OpenGL (MuJoCo), bpy and the browser tests,
# a Python 3.13 (else 3.11) virtual environment in .venv, and the project with its test extras (editable).
set -euo pipefail
cd "$(dirname "$0")/.."

# Headless GL (EGL through Mesa, OSMesa as the fallback) and the X libraries bpy links against.
# Headless Chromium and its driver: the results site's browser tests (`muble site`, tests/app/test_app_site.py).
APT_PACKAGES=(libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri libosmesa6 libglu1-mesa libx11-6 libxrender1 libxi6
              libxxf86vm1 libxfixes3 libxkbcommon0 libsm6 chromium chromium-driver)
missing=()
for p in "${APT_PACKAGES[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
if [ ${#missing[@]} -gt 0 ]; then
  echo "installing system packages: ${missing[*]}"
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# Python 3.13 (bpy 5.2, numpy 2, LeRobot 0.6) by default, from PATH or pyenv; 3.11 (bpy 5.0) where it is the only one.
# PYTHON=... chooses another supported one (3.11 to 3.13; 3.12 has no bpy build, so no Blender renderer).
find_python() {
  local c
  for c in python3.13 "$(pyenv root 2>/dev/null)"/versions/3.13*/bin/python3 "$HOME"/.pyenv/versions/3.13*/bin/python3 \
           python3.11; do
    # Run it: a pyenv shim exists for every installed version but fails for one that is not selected.
    "$c" -c 'import sys' >/dev/null 2>&1 && { command -v "$c"; return; }
  done
}
PYTHON=${PYTHON:-$(find_python)}
[ -n "$PYTHON" ] && command -v "$PYTHON" >/dev/null || {
  echo "MuBlE needs Python 3.13 (or 3.11, 3.12): none found; install one or set PYTHON=" >&2; exit 1; }
version=$("$PYTHON" -c 'import sys; print("%d.%d" % sys.version_info[:2])')
case "$version" in 3.11|3.12|3.13) ;; *) echo "MuBlE supports Python 3.11 to 3.13, not $version ($PYTHON)" >&2; exit 1;; esac
# A venv made with another Python is rebuilt (its compiled packages would not load).
if [ -x .venv/bin/python ] && [ "$(.venv/bin/python -c 'import sys; print("%d.%d" % sys.version_info[:2])')" != "$version" ]; then
  echo "rebuilding .venv for Python $version"
  rm -rf .venv
fi
[ -x .venv/bin/python ] || "$PYTHON" -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -e ".[test]"
if [ "$version" = "3.13" ]; then
  # robosuite 1.5.2 pins mink 0.0.5, which caps numpy below 2, and numpy 1 has no 3.13 build; robosuite never
  # imports mink, so it goes in without its declared dependencies (its runtime ones are in pyproject.toml).
  # Last, and with --no-deps, pip checks no dependencies: installed before the project, its missing mink made
  # pip end the project's install with "ERROR: ... robosuite 1.5.2 requires mink ...".
  .venv/bin/python -m pip install --quiet --no-deps robosuite==1.5.2
fi
echo "MuBlE installed in $(pwd)/.venv (Python $version)"
