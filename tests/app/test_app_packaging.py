"""Packaging: building the project prints no warnings of its own making (license metadata, data folders not
listed as packages), and the wheel carries every config file."""
from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BUILD_INPUTS = ("pyproject.toml", "setup.py", "README.md", "muble", "muble_plugins", "muble_conf")


def test_wheel_builds_without_warnings_and_ships_the_configs(tmp_path):
    source = tmp_path / "src"
    for name in BUILD_INPUTS:  # a copy: building in place would leave build/ in the working tree
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, source / name, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
        else:
            source.mkdir(exist_ok=True)
            shutil.copy2(src, source / name)
    result = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-v",
                             str(source), "-w", str(tmp_path / "dist")], capture_output=True, text=True,
                            timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    output = result.stdout + result.stderr
    # A deprecation said by setuptools or pip, not a file whose name has the word (muble/plugins/deprecated.py).
    for noise in ("Warning:", "is absent from the `packages`", "is deprecated", "DeprecationWarning"):
        assert noise not in output, [line for line in output.splitlines() if noise in line][:5]
    (wheel,) = (tmp_path / "dist").glob("muble-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    configs = {str(p.relative_to(ROOT)) for p in (ROOT / "muble_conf").rglob("*.yaml")}
    assert configs <= names, sorted(configs - names)
    # The frozen protocols' shipped splits and their manifests, and the wheel still small with them.
    shipped = {str(p.relative_to(ROOT)) for pattern in ("*.tar.xz", "*.json")
               for p in (ROOT / "muble_conf" / "protocol").glob(pattern)}
    assert shipped and shipped <= names, sorted(shipped - names)
    assert wheel.stat().st_size < 12 * 2**20, wheel.stat().st_size
