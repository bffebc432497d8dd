"""The sidebar panels, drawn into a recording layout (no UI in background)."""

import json
import types

import bpy
import pytest


class RecordingLayout:
    """Stands in for `UILayout`: records what is drawn, checks property names."""

    def __init__(self, log=None, icons=None):
        self.log = log if log is not None else []
        self.icons = icons if icons is not None else []  # (icon, text, alert) of each label
        self.use_property_split = False
        self.use_property_decorate = True
        self.enabled = True
        self.alert = False

    def _child(self, *_args, **_kwargs):
        return RecordingLayout(self.log, self.icons)

    column = row = box = split = _child

    def prop(self, data, name, text=None, **kwargs):
        assert name in data.bl_rna.properties, name
        self.log.append(("prop", name))

    def label(self, text="", icon='NONE', **kwargs):
        self.log.append(("label", text))
        self.icons.append((icon, text, self.alert))

    def operator(self, idname, **kwargs):
        self.log.append(("operator", idname))

    def progress(self, factor=0.0, type='BAR', text=""):
        self.log.append(("progress", factor))

    def separator(self, **kwargs):
        pass


def draw(panel_class, layout=None):
    layout = layout or RecordingLayout()
    panel = types.SimpleNamespace(layout=layout, draw_button=getattr(panel_class, "draw_button", None))
    panel_class.draw(panel, bpy.context)
    return layout.log


def draw_icons(panel_class):
    """The labels drawn, as (icon, text, alert)."""
    layout = RecordingLayout()
    draw(panel_class, layout)
    return layout.icons


def test_main_panel(addon, core, empty_scene):
    log = draw(addon.build_render.panel.BSPLAB_PT_main)
    props = [name for kind, name in log if kind == "prop"]
    assert props[0] == "method"
    params = core.methods()[empty_scene.bsplab.method]["params"]
    for name in ("traversal_cost", "intersect_cost", "empty_bonus", "max_depth", "leaf_size",
                 "leaf_boxes"):
        assert (name in props) == (name in params)
    for name in ("preview_percentage", "render_mode", "compare_with_embree", "threads", "cull",
                 "count_steps"):
        assert name in props
    assert ("operator", "bsplab.build_render") in log
    assert ("label", "80 x 60 px") not in log  # factory resolution, not the test scene's


def test_main_panel_while_running(addon, empty_scene, monkeypatch):
    job = types.SimpleNamespace(fraction=lambda: 0.25, title="Building & Rendering")
    monkeypatch.setattr(addon.state.STATE, "job", job)
    log = draw(addon.build_render.panel.BSPLAB_PT_main)
    assert ("operator", "bsplab.build_render") not in log
    assert ("label", "Esc to cancel") in log
    if addon.build_render.panel.HAS_PROGRESS_BAR:
        assert ("progress", 0.25) in log
    else:
        # Blender < 4.0 has no progress bar widget: a label says how far.
        assert ("label", "Building & Rendering 25%") in log
    # The sweep panel hides its button while any job runs; the main panel
    # shows that job's own title.
    assert ("operator", "bsplab.sweep_k") not in draw(addon.k_sweep.panel.BSPLAB_PT_sweep)
    job.title = "Sweeping K"
    log = draw(addon.build_render.panel.BSPLAB_PT_main)
    assert ("label", "Esc to cancel") in log
    if not addon.build_render.panel.HAS_PROGRESS_BAR:
        assert ("label", "Sweeping K 25%") in log


def test_stats_panel(addon, empty_scene):
    assert draw(addon.build_render.panel.BSPLAB_PT_stats) == [("label", "Press Build & Render")]
    empty_scene.bsplab.stats_json = json.dumps({
        "scene": {"triangles": 12, "objects": 1, "instances": 1},
        "build": {"build_seconds": 0.5, "nodes": 7, "leaves": 4, "empty_leaves": 1,
                  "max_depth": 3, "mean_leaf_depth": 2.5, "mean_leaf_size": 3.0,
                  "max_leaf_size": 5, "references": 15, "duplication": 1.25,
                  "bytes": 4096, "method": "kd"},
        "render": {"seconds": 0.01, "rays_per_second": 2.5e6, "mean_steps": 4.0,
                   "mean_tests": 2.0, "hits": 10, "width": 4, "height": 3,
                   "kernel": "avx2", "packets": True},
        "embree": {"available": False, "message": "embreex is not installed"},
    })
    texts = [text for kind, text in draw(addon.build_render.panel.BSPLAB_PT_stats) if kind == "label"]
    for expected in ("Build Time", "500.0 ms", "Nodes", "7", "Leaves", "4", "Empty Leaves", "1",
                     "Tris / Leaf", "3.00", "Max Leaf Tris", "5", "References", "15",
                     "Duplication", "1.25x", "Memory", "4.0 KiB", "Render Time", "10.0 ms",
                     "Rays/s", "2.50 M", "Kernel", "avx2, packets",
                     "Steps / Ray", "4.00", "Tests / Ray", "2.00",
                     "embreex is not installed"):
        assert expected in texts


DEGENERATE = ("degenerate tree: one leaf holds 180 of the 206 triangles (87%), "
              "so every ray reaching it tests them all")


def test_stats_panel_warns_of_a_degenerate_tree(addon, empty_scene):
    build = {"build_seconds": 0.5, "nodes": 3, "leaves": 2, "method": "kd", "warnings": []}
    empty_scene.bsplab.stats_json = json.dumps({"build": build})
    assert not any(icon == 'ERROR' for icon, _, _ in draw_icons(addon.build_render.panel.BSPLAB_PT_stats))
    build["warnings"] = [DEGENERATE]
    empty_scene.bsplab.stats_json = json.dumps({"build": build})
    labels = draw_icons(addon.build_render.panel.BSPLAB_PT_stats)
    lines = addon.build_render.statistics.warning_lines(DEGENERATE)
    # Wrapped for the narrow sidebar, in red, the first line with the alert icon.
    assert lines[0] == "Degenerate tree:"
    assert " ".join(lines[1:]) == DEGENERATE[len("degenerate tree: "):]
    assert all(len(line) <= addon.build_render.statistics.WARNING_WIDTH for line in lines)
    assert ('ERROR', lines[0], True) in labels
    assert [text for _, text, alert in labels if alert] == lines
    # Right after the Build rows, before the Render box.
    texts = [text for _, text, _ in labels]
    assert texts.index("Leaf Boxes") < texts.index(lines[0]) < texts.index("Render")
    assert "WARNING: " + DEGENERATE in addon.build_render.statistics.table({"build": build})


def test_build_of_a_degenerate_tree_shows_the_warning(addon, core, test_scene):
    """The whole way: a one-level tree over the test scene leaves most of its
    triangles in one leaf; the core says so and the panel shows it."""
    scene = test_scene["scene"]
    scene.bsplab.max_depth = 1
    assert bpy.ops.bsplab.build_render() == {'FINISHED'}
    warnings = scene.bsplab.stats["build"]["warnings"]
    assert warnings and warnings[0].startswith("degenerate tree: one leaf holds")
    labels = draw_icons(addon.build_render.panel.BSPLAB_PT_stats)
    assert ('ERROR', addon.build_render.statistics.warning_lines(warnings[0])[0], True) in labels
    scene.bsplab.max_depth = 0
    assert bpy.ops.bsplab.build_render() == {'FINISHED'}
    assert scene.bsplab.stats["build"]["warnings"] == []
    assert not any(icon == 'ERROR' for icon, _, _ in draw_icons(addon.build_render.panel.BSPLAB_PT_stats))


def test_build_says_its_quality(addon, core, test_scene):
    """The panel's default press builds fast (a quick first preview) and says
    so; exact builds the registry's exact tree and says that."""
    scene = test_scene["scene"]
    assert scene.bsplab.build_quality == "fast"
    assert bpy.ops.bsplab.build_render() == {'FINISHED'}
    assert scene.bsplab.stats["build"]["build_quality"] == "fast"
    texts = [text for kind, text in draw(addon.build_render.panel.BSPLAB_PT_stats) if kind == "label"]
    assert texts[texts.index("Build Quality") + 1] == "fast"
    scene.bsplab.build_quality = "exact"
    try:
        assert bpy.ops.bsplab.build_render() == {'FINISHED'}
        assert scene.bsplab.stats["build"]["build_quality"] == "exact"
        assert scene.bsplab.stats["build"]["reused"] is False  # another tree: built anew
    finally:
        scene.bsplab.build_quality = "fast"


@pytest.mark.parametrize("agreement", [1.0, 0.99])
def test_stats_embree_rows(addon, agreement):
    rows = dict(addon.build_render.statistics.embree_rows({
        "available": True, "bsplab_seconds": 0.02, "embree_seconds": 0.01, "time_ratio": 2.0,
        "compare": {"rays": 100, "agree": int(agreement * 100), "agreement": agreement,
                    "embree_wrong": 2, "grazing": 1, "at_ends": 0, "bsplab_wrong": 0,
                    "undecided": 0}}))
    assert rows["Time Ratio"] == "2.00x Embree"
    assert rows["Agreement"] == "{:.4%}".format(agreement)
    assert rows["Disagreeing"] == str(100 - int(agreement * 100))
    assert rows["Embree Wrong"] == "2"
    assert rows["At Edges"] == "1"
    assert rows["BSP Lab Wrong"] == rows["Undecided"] == "0"


def test_panel_shows_the_methods_own_params(addon, core, empty_scene):
    for method, info in core.methods().items():
        empty_scene.bsplab.method = method
        props = [name for kind, name in draw(addon.build_render.panel.BSPLAB_PT_main) if kind == "prop"]
        for name in addon.tree_options.BUILD_OPTIONS:
            expected = name in info["params"] or name == "threads"
            assert (name in props) == expected, (method, name)


def test_feature_panels_start_closed_with_their_tick_box_in_the_header(addon, empty_scene):
    for cls, toggle in ((addon.compare.panel.BSPLAB_PT_compare, ("bsplab_compare", "enabled")),
                        (addon.overlay.panel.BSPLAB_PT_overlay, ("bsplab_overlay", "show"))):
        assert cls.bl_options == {'DEFAULT_CLOSED'} and cls.TOGGLE == toggle
        layout = RecordingLayout()
        cls.draw_header(types.SimpleNamespace(layout=layout, TOGGLE=cls.TOGGLE), bpy.context)
        assert layout.log[0] == ("prop", toggle[1])
    # Every sub-panel's idname is its class name, the one Blender registers.
    for name in addon.sidebar.SUB_PANEL_ORDER:
        assert getattr(bpy.types, name).bl_idname == name
