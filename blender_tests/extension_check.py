"""Install the extension zip headless and press its button, in a fresh process.

    python extension_check.py ZIP          (a Python with the bpy module)

Run by test_extension.py without PYTHONPATH and with an empty Blender user
directory (BLENDER_USER_RESOURCES), so `bsplab` can only come from the wheels
bundled in the zip. Prints one line "EXTENSION_CHECK {json}".
"""

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

    scene = utils.press_on_test_scene(out)

    # embreex comes from the bundled wheel as well.
    scene.bsplab.compare_with_embree = True
    bpy.ops.bsplab.build_render()
    out["embree"] = scene.bsplab.stats.get("embree")
    # An Embree library this Blender exports (Debian 13's links libembree4)
    # makes the add-on decline the comparison instead of crashing.
    out["foreign_embree"] = bsplab.oracle.foreign_embree_library()
    return out


if __name__ == "__main__":
    utils.print_report_and_exit("EXTENSION_CHECK", main, sys.argv[-1])
