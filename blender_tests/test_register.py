"""Registration, the manifest and bl_info."""

import ast
import sys

import bpy
import pytest

import bsplab_test_utils as utils

CLASS_NAMES = ("BSPLAB_OT_build_render", "BSPLAB_PT_main", "BSPLAB_PT_stats")


def registered():
    return {name: hasattr(bpy.types, name) for name in CLASS_NAMES}


def test_register_unregister_reregister(addon):
    assert all(registered().values())
    assert hasattr(bpy.types.Scene, "bsplab")

    addon.unregister()
    assert not any(registered().values())
    assert not hasattr(bpy.types.Scene, "bsplab")
    assert not hasattr(bpy.types.WindowManager, "bsplab_job")
    addon.unregister()  # a second unregister is a no-op

    addon.register()
    addon.register()  # registering again starts over instead of failing
    assert all(registered().values())
    scene = utils.reset_file()
    assert scene.bsplab.preview_percentage == 50
    assert bpy.ops.bsplab.build_render.poll()


def test_registers_and_draws_without_core(addon, monkeypatch):
    """The add-on registers with the core missing; its enum falls back."""
    monkeypatch.setitem(sys.modules, "bsplab", None)  # makes `import bsplab` fail
    addon.unregister()
    addon.register()
    scene = utils.reset_file()
    assert scene.bsplab.method == "kd"
    assert scene.bsplab.render_mode == "shaded"
    assert addon.backend.core_or_none() is None


def test_method_enum_follows_core(addon, core):
    scene = utils.reset_file()
    names = [item[0] for item in addon.properties._method_enum_items(scene.bsplab, bpy.context)]
    assert names == list(core.methods())
    assert scene.bsplab.method in core.methods()
    modes = [item[0] for item in addon.properties._mode_enum_items(scene.bsplab, bpy.context)]
    assert modes == list(core.RENDER_MODES)


def test_bl_info_for_legacy_blender():
    source = (utils.ADDON_DIR / "__init__.py").read_text()
    tree = ast.parse(source)
    bl_info = next(ast.literal_eval(node.value) for node in tree.body
                   if isinstance(node, ast.Assign) and node.targets[0].id == "bl_info")
    assert bl_info["blender"] <= (3, 4, 0)
    assert bl_info["name"] == "BSP Lab"
    assert "register_classes_factory" in source


def test_manifest_fields():
    tomllib = pytest.importorskip("tomllib")
    manifest = tomllib.loads((utils.ADDON_DIR / "blender_manifest.toml").read_text())
    assert manifest["schema_version"] == "1.0.0"
    assert manifest["id"] == "bsplab"
    assert manifest["type"] == "add-on"
    assert manifest["blender_version_min"] == "4.2.0"
    assert manifest["platforms"] == ["linux-x64"]


def test_reload_scripts(addon):
    """What F8 / Reload Scripts does: unregister, reload, register."""
    import importlib
    old_operator = addon.operators.BSPLAB_OT_build_render
    addon.unregister()
    try:
        importlib.reload(addon)
    finally:
        addon.register()  # the other tests need it registered either way
    assert addon.operators.BSPLAB_OT_build_render is not old_operator
    assert bpy.types.BSPLAB_OT_build_render is addon.operators.BSPLAB_OT_build_render
    utils.reset_file()
    assert bpy.ops.bsplab.build_render.poll()
