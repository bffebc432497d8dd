"""bsplab.blender: the scene readers the add-on and io.load_blend share,
importable without bpy, shipped (with the export script) inside the package."""

import ast
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import bsplab
from bsplab import blender, io
from bsplab.blender import extract, scene_camera

PACKAGE = Path(bsplab.__file__).resolve().parent


def test_the_export_script_ships_inside_the_installed_package():
    assert blender.EXPORT_SCRIPT.is_file()
    assert blender.EXPORT_SCRIPT.resolve().parent == PACKAGE / "blender"


@pytest.mark.parametrize("module", [scene_camera, extract])
def test_readers_run_as_plain_modules(module):
    """export_scene.py imports them from their folder in a Blender whose Python
    may not load the compiled core: they import only the stdlib and numpy."""
    tree = ast.parse(Path(module.__file__).read_text())
    imported = {alias.name.split(".")[0] for node in ast.walk(tree)
                if isinstance(node, ast.Import) for alias in node.names}
    imported |= {node.module.split(".")[0] for node in ast.walk(tree)
                 if isinstance(node, ast.ImportFrom) and node.level == 0}
    assert not any(isinstance(node, ast.ImportFrom) and node.level for node in ast.walk(tree))
    assert imported <= {"dataclasses", "numpy"}, imported


def test_load_blend_runs_the_packaged_script(tmp_path, monkeypatch):
    """With a Python that has no bpy as the 'Blender', the packaged script is
    what runs (and fails on `import bpy`), reported with its output."""
    if not Path(sys.executable).name.startswith("python"):
        pytest.skip("load_blend tells a Python from a Blender by its name")
    try:
        subprocess.run([sys.executable, "-c", "import bpy"], check=True, capture_output=True)
        pytest.skip("this Python has the bpy module")
    except subprocess.CalledProcessError:
        pass
    scene = tmp_path / "scene.blend"
    scene.write_bytes(b"BLENDER")
    monkeypatch.setenv("BSPLAB_BLENDER", sys.executable)
    with pytest.raises(RuntimeError, match="Blender could not export scene.blend") as err:
        io.load_blend(scene)
    message = str(err.value)
    assert str(blender.EXPORT_SCRIPT) in message and "bpy" in message


def test_camera_spec_makes_a_core_camera():
    spec = scene_camera.CameraSpec(matrix_world=np.eye(4), lens=35.0, sensor_width=36.0,
                             sensor_height=24.0, sensor_fit="AUTO", shift_x=0.1, shift_y=0.0,
                             pixel_aspect=1.0, clip_start=0.1, clip_end=100.0, width=64,
                             height=48, name="Cam")
    cam = bsplab.Camera(**spec.kwargs())
    origins, directions = cam.rays(spec.width, spec.height)
    assert origins.shape == directions.shape == (64 * 48, 3)
