"""Install the legacy add-on zip headless and press its button, in a fresh process.

    python legacy_check.py ZIP                                   (bpy module)
    blender -b --factory-startup --python legacy_check.py -- ZIP (Blender)

Run by test_extension.py with an empty Blender user directory. The core
comes from PYTHONPATH / BSPLAB_PYTHONPATH: legacy add-ons bundle no wheels.
Prints one line "LEGACY_CHECK {json}".
"""

import pathlib
import sys

import bpy

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import bsplab_test_utils as utils  # noqa: E402


def main(zip_path):
    import addon_utils
    utils.add_core_paths()
    out = {"blender": bpy.app.version_string}
    out["install"] = sorted(bpy.ops.preferences.addon_install(filepath=zip_path, overwrite=True))
    module = addon_utils.enable("bsplab_addon", default_set=True, handle_error=None)
    out["enabled"] = module is not None
    out["module_file"] = getattr(module, "__file__", None)
    utils.press_on_test_scene(out)
    addon_utils.disable("bsplab_addon", default_set=True)
    out["unregistered"] = not hasattr(bpy.types.Scene, "bsplab")
    return out


if __name__ == "__main__":
    utils.print_report_and_exit("LEGACY_CHECK", main, sys.argv[-1])
