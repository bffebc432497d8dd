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
    assert addon.backend.bsplab_or_none() is None


def test_method_enum_follows_core(addon, core):
    scene = utils.reset_file()
    names = [item[0] for item in addon.tree_options.method_enum_items(scene.bsplab, bpy.context)]
    assert names == list(core.methods())
    assert scene.bsplab.method in core.methods()
    modes = [item[0] for item in addon.build_render.properties._mode_enum_items(scene.bsplab, bpy.context)]
    assert modes == list(core.RENDER_MODES)


def test_bl_info_for_legacy_blender():
    source = (utils.ADDON_DIR / "__init__.py").read_text()
    tree = ast.parse(source)
    bl_info = next(ast.literal_eval(node.value) for node in tree.body
                   if isinstance(node, ast.Assign) and node.targets[0].id == "bl_info")
    assert bl_info["blender"] <= (3, 4, 0)
    assert bl_info["name"] == "BSP Lab"
    # The features register through bpy.utils.register_classes_factory
    # (there since 2.80), not a newer helper.
    assert "register_classes_factory" in (utils.ADDON_DIR / "registration.py").read_text()


def test_every_subpackage_is_a_registered_feature(addon):
    """Adding a feature is one subpackage and one line in FEATURES: every
    subpackage is listed, in a folder of its own, with `classes`,
    `register()` and `unregister()`; every class of a feature is
    registered."""
    folders = sorted(p.parent.name for p in utils.ADDON_DIR.glob("*/__init__.py"))
    features = {feature.__name__.rpartition(".")[2]: feature for feature in addon.FEATURES}
    assert sorted(features) == folders
    for name, feature in features.items():
        assert callable(feature.register) and callable(feature.unregister), name
        for cls in feature.classes:
            assert cls.is_registered, (name, cls)


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
    old_operator = addon.build_render.operator.BSPLAB_OT_build_render
    addon.unregister()
    try:
        importlib.reload(addon)
    finally:
        addon.register()  # the other tests need it registered either way
    assert addon.build_render.operator.BSPLAB_OT_build_render is not old_operator
    assert bpy.types.BSPLAB_OT_build_render is addon.build_render.operator.BSPLAB_OT_build_render
    utils.reset_file()
    assert bpy.ops.bsplab.build_render.poll()


def test_option_properties_follow_the_registry(addon, core):
    """Every build option's property: name, help, default and limits from the
    core's registry, not retyped in the add-on; the panel's own defaults
    (PANEL_DEFAULTS: the fast build for a quick first preview) and those of
    the method a new scene starts at (kd's fast bins) excepted."""
    schema = core.option_schema()
    first = next(iter(core.methods().values()))["defaults"]
    shown = [name for name in schema if name not in addon.tree_options.HIDDEN_OPTIONS
             and schema[name]["group"] != "top"]  # a two-level build's top level's
    assert sorted(addon.tree_options.BUILD_OPTIONS) == sorted(shown)
    rna = addon.build_render.properties.BSPLabSettings.bl_rna.properties
    for name in addon.tree_options.BUILD_OPTIONS:
        spec, prop = schema[name], rna[name]
        assert (prop.name, prop.description) == (spec["label"], spec["help"]), name
        assert addon.tree_options.SHORT_LABELS[name] == spec["short_label"]
        default = addon.tree_options.PANEL_DEFAULTS.get(name, first.get(name, spec["default"]))
        if spec["type"] == "enum":
            assert prop.default == default, name
            assert [(i.identifier, i.name, i.description) for i in prop.enum_items] == \
                [(c["name"], c["label"], c["help"]) for c in spec["choices"]]
            continue
        assert prop.default == pytest.approx(default), name
        if spec["min"] is not None:
            step = addon.tree_options.OPEN_MIN_STEP if spec["min_open"] else 0
            assert prop.hard_min == pytest.approx(spec["min"] + step), name
        if spec["max"] is not None:
            assert prop.hard_max == pytest.approx(min(spec["max"], 2**31 - 1)), name
        if spec["soft_max"] is not None:
            assert prop.soft_max == pytest.approx(spec["soft_max"]), name


def test_the_button_builds_fast_by_default(addon, core):
    """The first preview is quick: the panel's build quality starts at fast,
    though the registry's (scripts', the lab's) default stays exact."""
    assert core.option_schema()["build_quality"]["default"] == "exact"
    rna = addon.build_render.properties.BSPLabSettings.bl_rna.properties
    assert rna["build_quality"].default == "fast"
    assert bpy.context.scene.bsplab.build_quality == "fast"


def test_method_defaults_fit_the_properties(addon, core):
    """Choosing a method loads its own defaults (K differs between methods)."""
    scene = utils.reset_file()
    panel = addon.tree_options.PANEL_DEFAULTS
    for method, info in core.methods().items():
        scene.bsplab.method = method
        for name, value in info["defaults"].items():
            if name in panel:  # the panel's own default stands (below)
                continue
            assert getattr(scene.bsplab, name) == pytest.approx(value), (method, name)


def test_choosing_a_method_keeps_the_build_quality(addon, core):
    """The methods' tables list build_quality's registry default (exact);
    choosing a method must not undo the panel's fast, nor the user's exact."""
    scene = utils.reset_file()
    assert scene.bsplab.build_quality == "fast"
    for method in ("bsp_wn+kd", "kd", "bsp_ize+kd"):
        scene.bsplab.method = method
        assert scene.bsplab.build_quality == "fast", method
    scene.bsplab.build_quality = "exact"
    scene.bsplab.method = "bsp_wn+kd"
    assert scene.bsplab.build_quality == "exact"


def test_fallback_render_modes_are_the_cores(addon, core):
    assert set(addon.backend.FALLBACK_RENDER_MODES) <= set(core.RENDER_MODES)


def test_loads_without_core_with_no_build_options(addon, monkeypatch):
    """Imported (not only registered) without the core: no option properties,
    since their schema is the core's, and the panel still draws."""
    import importlib
    monkeypatch.setitem(sys.modules, "bsplab", None)
    addon.unregister()
    try:
        importlib.reload(addon)
        addon.register()
        assert addon.tree_options.BUILD_OPTIONS == ()
        scene = utils.reset_file()
        assert scene.bsplab.method == "kd" and not hasattr(scene.bsplab, "k")
    finally:
        addon.unregister()
        monkeypatch.undo()
        importlib.reload(addon)
        addon.register()  # the other tests need it registered with the core
    assert "k" in addon.tree_options.BUILD_OPTIONS
