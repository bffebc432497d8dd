"""Install the extension zip headless and press its button, in a fresh process.

    python extension_check.py ZIP          (a Python with the bpy module)

Run by test_extension.py without PYTHONPATH and with an empty Blender user
directory (BLENDER_USER_RESOURCES), so `bsplab` can only come from the wheels
bundled in the zip. Prints one line "EXTENSION_CHECK {json}".
"""

import json
import os
import pathlib
import sys

import bpy

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import bsplab_test_utils as utils  # noqa: E402


def main(zip_path):
    out = {"blender": bpy.app.version_string}
    try:
        import bsplab  # noqa: F401
        out["core_before_install"] = bsplab.__file__
    except ImportError:
        out["core_before_install"] = None

    result = bpy.ops.extensions.package_install_files(
        filepath=zip_path, repo="user_default", enable_on_install=True)
    out["install"] = sorted(result)
    out["addons"] = sorted(a.module for a in bpy.context.preferences.addons)

    import bsplab
    out["core"] = bsplab.__file__

    # Build the test scene in the current file: loading factory settings
    # would also reset the preferences that enable the extension.
    scene = bpy.context.scene
    for obj in list(scene.objects):
        bpy.data.objects.remove(obj)
    utils.build_test_scene(scene)
    out["operator"] = sorted(bpy.ops.bsplab.build_render())
    image = bpy.data.images.get("BSP Lab Preview")
    out["image_size"] = list(image.size) if image else None
    out["triangles"] = scene.bsplab.stats.get("scene", {}).get("triangles")

    # embreex comes from the bundled wheel as well.
    scene.bsplab.compare_with_embree = True
    bpy.ops.bsplab.build_render()
    out["embree"] = scene.bsplab.stats.get("embree")
    return out


if __name__ == "__main__":
    try:
        report = main(sys.argv[-1])
    except Exception as ex:  # reported to the test, which fails on it
        report = {"error": "{}: {}".format(type(ex).__name__, ex)}
    print("EXTENSION_CHECK " + json.dumps(report), flush=True)
    sys.stderr.flush()
    # Skip the bpy 4.2 module's crash in static destructors at exit.
    os._exit(0)
