# SPDX-License-Identifier: GPL-3.0-or-later
"""Writes a .blend's evaluated triangles and scene camera to an .npz file.

Run by `bsplab.io.load_blend()` (the experiment runner's .blend scenes) in a
Blender process, or in a Python with the `bpy` module:

    blender -b scene.blend --python .../bsplab/blender/export_scene.py -- out.npz
    python .../bsplab/blender/export_scene.py -- out.npz scene.blend

It uses extract.py and scene_camera.py beside it, imported as plain modules: this
Blender's Python need not be able to load the compiled core (`import bsplab`).
The add-on uses the same two modules, so an experiment sees exactly the
triangles and camera that Build & Render sees.
"""

import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scene_camera  # noqa: E402  (bsplab/blender's modules, imported as plain modules)
import extract  # noqa: E402


def main(argv):
    args = argv[argv.index("--") + 1:] if "--" in argv else []
    if not args:
        raise SystemExit("usage: export_scene.py -- OUT.npz [SCENE.blend]")
    if len(args) > 1:
        bpy.ops.wm.open_mainfile(filepath=args[1])
    scene = bpy.context.scene
    depsgraph = bpy.context.evaluated_depsgraph_get()
    geometry = extract.scene_triangles(depsgraph)
    out = {"triangles": geometry.triangles}
    try:
        spec = scene_camera.scene_camera(scene, depsgraph, 100)
    except scene_camera.CameraError as ex:
        out["camera_error"] = np.array(str(ex))
    else:
        for key, value in spec.kwargs().items():
            out["camera_" + key] = np.asarray(value)
        out["camera_size"] = np.array([spec.width, spec.height])
    np.savez(args[0], **out)
    print("export_scene: {} triangles -> {}".format(len(geometry.triangles), args[0]))


main(sys.argv)
if not bpy.app.binary_path:
    # The bpy module (4.2) can crash in its exit-time destructors; the file
    # is written, so leave before they run.
    sys.stdout.flush()
    os._exit(0)
