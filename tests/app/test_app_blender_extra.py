"""Blender is an extra: without bpy the plugin is still listed, and choosing it is a usage error naming the extra."""
from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

# Runs the `muble` command in a Python where `import bpy` fails as it does when the module is not installed
# (a meta-path finder refuses it before the installed one is found).
WITHOUT_BPY = textwrap.dedent("""
    import importlib.abc, sys

    class NoBpy(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name == "bpy" or name.startswith("bpy."):
                raise ModuleNotFoundError("No module named 'bpy'", name="bpy")
            return None

    sys.meta_path.insert(0, NoBpy())
    from muble.app.cli import main
    sys.exit(main(sys.argv[1:]))
""")


def _muble_without_bpy(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", WITHOUT_BPY, *args], capture_output=True, text=True, timeout=600)


def test_blender_renderer_without_bpy_exits_2_naming_the_extra(tmp_path):
    result = _muble_without_bpy("renderer=blender", "dry_run=true", f"hydra.run.dir={tmp_path / 'run'}")
    assert result.returncode == 2, result.stdout + result.stderr
    assert 'pip install "muble[blender]"' in result.stderr and "bpy" in result.stderr
    assert "Traceback" not in result.stderr, result.stderr[-2000:]
    assert result.stderr.strip().count("\n") == 0, result.stderr  # one paragraph


def test_render_command_without_bpy_exits_2_and_writes_nothing(tmp_path):
    scene = Path(__file__).parents[1] / "tasks" / "data" / "left_part_full.json"  # a SHOP-VRB2 scene file
    out = tmp_path / "renders"
    result = _muble_without_bpy("render", str(scene), "--out", str(out))  # `muble render` uses Blender by default
    assert result.returncode == 2, result.stdout + result.stderr
    assert 'pip install "muble[blender]"' in result.stderr
    assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".muble-tmp-")]


def test_blender_plugin_is_listed_without_bpy():
    result = _muble_without_bpy("plugins", "--kind", "renderer", "--json")
    assert result.returncode == 0, result.stderr
    assert {"blender", "mujoco"} <= {row["name"] for row in json.loads(result.stdout)}
