"""addon/tools/demo_headless.py, the README's Blender demo, in a fresh process."""

import os
import subprocess
import sys

import bpy

import bsplab_test_utils as utils
from conftest import in_bpy_module

DEMO = str(utils.REPO / "addon/tools" / "demo_headless.py")


def run_demo(*args):
    if in_bpy_module():
        cmd = [sys.executable, DEMO, *args]
    else:
        cmd = [bpy.app.binary_path, "--background", "--factory-startup", "-noaudio",
               "--python", DEMO, "--", *args]
    env = dict(os.environ)
    # Blender's Python ignores PYTHONPATH: hand the core's folders on.
    env["BSPLAB_PYTHONPATH"] = os.pathsep.join(
        p for p in (env.get("BSPLAB_PYTHONPATH"), env.get("PYTHONPATH")) if p)
    return subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)


def png_size(path):
    with open(path, "rb") as f:
        header = f.read(24)
    assert header[:8] == b"\x89PNG\r\n\x1a\n"
    return int.from_bytes(header[16:20], "big"), int.from_bytes(header[20:24], "big")


def test_demo_generates_renders_and_prints(core, tmp_path):
    out = tmp_path / "demo.png"
    # The add-on's default: its instanced collection in two levels.
    result = run_demo("--out", str(out), "--resolution", "160x90", "--mode", "normal")
    assert result.returncode == 0, result.stdout + result.stderr
    assert png_size(out) == (160, 90)
    for row in ("Triangles", "Built As        two-level", "Build Time", "Unique Meshes",
                "Top Nodes", "Mesh Nodes", "Flattened Tris", "Rays/s", "Saved"):
        assert row in result.stdout
    result = run_demo("--out", str(out), "--resolution", "160x90", "--mode", "normal",
                      "--instances", "flatten")
    assert result.returncode == 0, result.stdout + result.stderr
    for row in ("Triangles", "Built As", "flatten", "Build Time", "Nodes", "Tris / Leaf",
                "Rays/s", "Saved"):
        assert row in result.stdout


def test_demo_opens_a_blend(addon, core, test_scene, tmp_path):
    blend = str(tmp_path / "scene.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    out = tmp_path / "from_blend.png"
    result = run_demo("--blend", blend, "--out", str(out), "--preview", "50")
    assert result.returncode == 0, result.stdout + result.stderr
    assert png_size(out) == (80, 60)
    assert "{:,}".format(utils.EXPECTED_TRIANGLES) in result.stdout


def test_demo_reports_errors(addon, core, empty_scene, tmp_path):
    """A scene without camera: the operator's message, exit code 1."""
    blend = str(tmp_path / "empty.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    result = run_demo("--blend", blend, "--out", str(tmp_path / "x.png"))
    assert result.returncode == 1
    assert "no active camera" in result.stderr
    assert not (tmp_path / "x.png").exists()
