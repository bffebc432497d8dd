"""The add-on's bpy-free modules (addon/jobs.py, sweep.py, legend.py, ...)
imported in the core's tests, without Blender."""

import importlib
import sys
import types
from pathlib import Path

ADDON_DIR = Path(__file__).resolve().parents[2] / "addon"
PACKAGE = "bsplab_addon_without_blender"


def addon_module(name):
    """addon/<name>.py imported as PACKAGE.<name>; the package's __init__ (which
    needs bpy) is not run."""
    if PACKAGE not in sys.modules:
        package = types.ModuleType(PACKAGE)
        package.__path__ = [str(ADDON_DIR)]
        sys.modules[PACKAGE] = package
    return importlib.import_module(f"{PACKAGE}.{name}")
