"""The add-on's bpy-free modules (addon/build_render/job.py,
k_sweep/experiment.py, drawing/legend.py, ...) imported in these tests,
without Blender."""

import importlib
import sys
import types
from pathlib import Path

ADDON_DIR = Path(__file__).resolve().parents[2] / "addon"
PACKAGE = "bsplab_addon_without_blender"


def _stub_packages():
    """The add-on's package and its feature subpackages as empty packages
    on their folders: their __init__.py files (which register with Blender)
    are not run, the modules inside import as usual."""
    for folder in [ADDON_DIR, *sorted(p.parent for p in ADDON_DIR.glob("*/__init__.py"))]:
        parts = folder.relative_to(ADDON_DIR).parts
        name = ".".join((PACKAGE, *parts))
        if name not in sys.modules:
            package = types.ModuleType(name)
            package.__path__ = [str(folder)]
            sys.modules[name] = package
            if parts:
                setattr(sys.modules[PACKAGE], parts[-1], package)


def addon_module(name):
    """addon/<name>.py ("build_render.job" for addon/build_render/job.py)
    imported as PACKAGE.<name>; no package's __init__ (which needs bpy) is run."""
    _stub_packages()
    return importlib.import_module(f"{PACKAGE}.{name}")
