"""Instanced scenes in two levels (issue 24): the extraction keeps the
instances (one mesh per evaluated mesh, object-space triangles, a world
matrix per instance) and reads curves, text, surfaces and metaballs; the
panel's Instances choice builds two levels or one flat tree; a press after
moving, adding or deleting an instance rebuilds the top level only, one
after editing a mesh that mesh's tree only; the statistics, Embree's
comparison and the errors of a two-level build."""

import math

import bpy
import numpy as np
import pytest

import bsplab_test_utils as utils
from test_ui import draw

GRID = 3  # collection instances in a GRID x GRID grid
SCATTER_POINTS = 4


def extract(addon, flat=False):
    reader = addon.jobs.scene_reader
    depsgraph = bpy.context.evaluated_depsgraph_get()
    return (reader.scene_triangles if flat else reader.scene_instances)(depsgraph)


def add_scatter(scene, source, location):
    """A mesh of SCATTER_POINTS vertices with a geometry-nodes modifier
    instancing `source` on them; None where this Blender's node API differs."""
    points = utils.make_mesh("Points", [(2.0 * i, 0, 0) for i in range(SCATTER_POINTS)], [])
    obj = utils.link(scene, "Scatter", points, location)
    group = bpy.data.node_groups.new("Scatter", 'GeometryNodeTree')
    if not hasattr(group, "interface"):  # Blender < 4.0
        bpy.data.objects.remove(obj)
        return None
    group.interface.new_socket("Geometry", in_out='INPUT', socket_type='NodeSocketGeometry')
    group.interface.new_socket("Geometry", in_out='OUTPUT', socket_type='NodeSocketGeometry')
    nodes, links = group.nodes, group.links
    given, out = nodes.new('NodeGroupInput'), nodes.new('NodeGroupOutput')
    on_points = nodes.new('GeometryNodeInstanceOnPoints')
    info = nodes.new('GeometryNodeObjectInfo')
    info.inputs['Object'].default_value = source
    links.new(given.outputs[0], on_points.inputs['Points'])
    links.new(info.outputs['Geometry'], on_points.inputs['Instance'])
    links.new(on_points.outputs['Instances'], out.inputs[0])
    obj.modifiers.new("Scatter", 'NODES').node_group = group
    return obj


def build_instanced_scene(scene):
    """Collection instances in a grid, linked duplicates (one mirrored), a
    geometry-nodes scatter, a curve with a bevel, a text, a metaball, a
    ground; the camera sees them all."""
    scene.render.resolution_x, scene.render.resolution_y = 160, 120
    scene.render.resolution_percentage = 100
    objects = {"scene": scene}
    objects["ground"] = utils.link(scene, "Ground", utils.quad_mesh("Ground", 40.0))

    # A collection (a cube and a tetrahedron) instanced GRID x GRID times.
    props = bpy.data.collections.new("Props")
    cube = bpy.data.objects.new("Prop Cube", utils.cube_mesh("Prop Cube", 0.8))
    cube.location = (0, 0, 0.4)
    props.objects.link(cube)
    tetra = bpy.data.objects.new("Prop Tetra", utils.tetra_mesh("Prop Tetra", 0.5))
    tetra.location = (0, 0, 1.2)
    props.objects.link(tetra)
    objects["grid"] = []
    for i in range(GRID):
        for j in range(GRID):
            empty = utils.link(scene, "Grid {} {}".format(i, j), None,
                               (-6.0 + 1.5 * i, 1.0 + 1.5 * j, 0.0))
            empty.instance_type = 'COLLECTION'
            empty.instance_collection = props
            empty.rotation_euler = (0, 0, 0.3 * (i + j))
            objects["grid"].append(empty)
    objects["props"] = props

    # Linked duplicates of one mesh; the last one mirrored (negative scale).
    shared = utils.tetra_mesh("Shared", 1.2)
    objects["duplicates"] = [utils.link(scene, "Duplicate {}".format(i), shared,
                                        (1.0 + 1.6 * i, 0.0, 0.7)) for i in range(3)]
    objects["duplicates"][2].scale = (-1.0, 1.0, 1.3)
    objects["shared"] = shared

    # A geometry-nodes scatter of a small cube.
    source = utils.link(scene, "Scatter Source", utils.cube_mesh("Scatter Cube", 0.4),
                        (0, 0, -50))  # itself out of view, below the ground
    source.hide_set(True)
    objects["scatter"] = add_scatter(scene, source, (-3.0, -2.5, 0.3))

    # Non-mesh surfaces.
    curve = bpy.data.curves.new("Pipe", 'CURVE')
    curve.dimensions = '3D'
    spline = curve.splines.new('BEZIER')
    spline.bezier_points.add(1)
    spline.bezier_points[0].co = (0, 0, 0)
    spline.bezier_points[1].co = (2, 0, 0)
    curve.bevel_depth = 0.15
    objects["curve"] = utils.link(scene, "Pipe", curve, (2.0, 3.0, 0.5))
    text = bpy.data.curves.new("Title", 'FONT')
    text.body = "BSP"
    text.extrude = 0.05
    objects["text"] = utils.link(scene, "Title", text, (-1.0, 5.0, 2.5))
    objects["text"].rotation_euler = (math.pi / 2, 0, 0)
    ball = bpy.data.metaballs.new("Ball")
    ball.elements.new().radius = 0.6
    ball.resolution = 0.2
    objects["meta"] = utils.link(scene, "Ball", ball, (4.0, 3.0, 1.0))

    objects["camera"] = utils.add_camera(scene, location=(0.0, -13.0, 7.0),
                                         target=(0.0, 2.0, 0.5))
    bpy.context.view_layer.update()
    return objects


@pytest.fixture
def instanced_scene(addon):
    return build_instanced_scene(utils.reset_file("two_level"))


def press(scene):
    assert bpy.ops.bsplab.build_render() == {'FINISHED'}
    return scene.bsplab.stats


def panel_rows(addon):
    """(label, text) pairs of the Statistics panel, as it draws them."""
    texts = [text for kind, text in draw(addon.build_render.panel.BSPLAB_PT_stats)
             if kind == "label"]
    return texts


def panel_row(addon, label):
    texts = panel_rows(addon)
    return texts[texts.index(label) + 1]


def preview_pixels(addon):
    image = bpy.data.images[addon.jobs.preview.IMAGE_NAME]
    return utils.image_pixels_top_down(image).copy()


# -----------------------------------------------------------------------------
# Extraction


def test_two_level_is_the_default(addon, core):
    assert utils.reset_file(instances="two_level").bsplab.instances == "two_level"
    bpy.ops.wm.read_factory_settings(use_empty=True)
    assert bpy.context.scene.bsplab.instances == "two_level"
    prop = bpy.context.scene.bsplab.bl_rna.properties["instances"]
    assert [item.name for item in prop.enum_items] == ["Two-level", "Flatten"]
    assert all(item.description for item in prop.enum_items) and prop.description


def test_the_instanced_extraction_keeps_the_instances(addon, core, instanced_scene):
    geo = extract(addon)
    flat = extract(addon, flat=True)
    names = geo.mesh_names
    # One entry per evaluated mesh: ground, the collection's cube and
    # tetrahedron, the duplicates' shared mesh, the scattered cube, the
    # pipe, the text, the metaball.
    scatter = instanced_scene["scatter"] is not None
    assert len(geo.meshes) == 7 + scatter, names
    for name in ("Ground", "Prop Cube", "Prop Tetra", "Duplicate 0", "Pipe", "Title", "Ball"):
        assert name in names
    counts = np.bincount(geo.mesh_index, minlength=len(geo.meshes))
    assert counts[names.index("Prop Cube")] == counts[names.index("Prop Tetra")] == GRID * GRID
    assert counts[names.index("Duplicate 0")] == 3  # the linked duplicates share it
    if scatter:
        assert counts[names.index("Scatter")] == SCATTER_POINTS
    assert len(geo.mesh_index) == len(geo.matrices) == len(geo.instance_names)
    assert len(geo.mesh_index) == 1 + 2 * GRID * GRID + 3 + SCATTER_POINTS * scatter + 3
    assert "'Prop Cube' in 'Grid 1 2'" in geo.instance_names
    # Object space: the collection's cube is 0.8 wide around its origin;
    # its instance matrix puts it at (0, 0, 0.4) in the grid empty's frame.
    cube = geo.meshes[names.index("Prop Cube")].reshape(-1, 3)
    assert np.allclose(cube.min(axis=0), (-0.4, -0.4, -0.4), atol=1e-6)
    empty = np.array(instanced_scene["grid"][GRID * 1 + 2].matrix_world)
    matrix = geo.matrices[geo.instance_names.index("'Prop Cube' in 'Grid 1 2'")]
    assert np.allclose(matrix[:, 3], (empty @ (0, 0, 0.4, 1))[:3], atol=1e-5)
    assert np.allclose(matrix[:, :3], empty[:3, :3], atol=1e-6)
    # The matrices are the instances' world matrices; the mirror's is negative.
    dets = np.linalg.det(geo.matrices[:, :, :3])
    assert (dets < 0).sum() == 1
    # The flattened scene is the flat extraction, triangle for triangle.
    assert geo.triangle_count == flat.triangle_count == len(geo.flatten())
    assert np.array_equal(geo.flatten(), flat.triangles)
    assert geo.objects == flat.objects and geo.instances == flat.instances
    assert geo.mesh_triangle_count < geo.triangle_count


def test_curves_text_and_metaballs_are_surfaces(addon, core, instanced_scene):
    flat = extract(addon, flat=True).triangles
    centres = flat.mean(axis=1)
    for key in ("curve", "text", "meta"):
        obj = instanced_scene[key]
        evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
        mesh = evaluated.to_mesh()
        mesh.calc_loop_triangles()
        expected = len(mesh.loop_triangles)
        evaluated.to_mesh_clear()
        assert expected > 0, key
        # Its triangles are in the scene, in world space around the object.
        box = np.array([list(corner) for corner in obj.bound_box])
        world = box @ np.array(obj.matrix_world)[:3, :3].T + np.array(obj.matrix_world)[:3, 3]
        inside = np.all((centres >= world.min(axis=0) - 1e-4) &
                        (centres <= world.max(axis=0) + 1e-4), axis=1)
        assert inside.sum() >= expected, key
    # A curve without a bevel or extrusion is no surface.
    plain = bpy.data.curves.new("Wire", 'CURVE')
    plain.splines.new('POLY').points.add(1)
    utils.link(instanced_scene["scene"], "Wire", plain)
    bpy.context.view_layer.update()
    assert extract(addon, flat=True).triangle_count == len(flat)


# -----------------------------------------------------------------------------
# Build & Render in two levels and flattened


def test_two_level_renders_what_flatten_renders(addon, core, instanced_scene):
    scene = instanced_scene["scene"]
    scene.bsplab.render_mode = "depth"
    two = press(scene)
    two_pixels = preview_pixels(addon)
    scene.bsplab.instances = "flatten"
    flat = press(scene)
    flat_pixels = preview_pixels(addon)
    assert two["build"]["structure"] == "two_level"
    assert flat["build"]["structure"] in ("bsp", "bvh")
    assert two["scene"]["triangles"] == flat["scene"]["triangles"] == flat["build"]["triangles"]
    assert two["render"]["hits"] > 0.3 * 80 * 60
    assert abs(two["render"]["hits"] - flat["render"]["hits"]) <= 3
    differ = (np.abs(two_pixels - flat_pixels).max(axis=2) > 1e-3).sum()
    assert differ <= 5, differ
    # Shaded too: normals carried to the world (a mirror flips them as the
    # flattened triangle's winding).
    scene.bsplab.render_mode = "shaded"
    press(scene)
    flat_shaded = preview_pixels(addon)
    scene.bsplab.instances = "two_level"
    press(scene)
    assert (np.abs(preview_pixels(addon) - flat_shaded).max(axis=2) > 1e-3).sum() <= 5


def test_the_statistics_show_both_levels(addon, core, instanced_scene):
    scene = instanced_scene["scene"]
    stats = press(scene)
    build = stats["build"]
    geo = extract(addon)
    assert build["meshes"] == len(geo.meshes)
    assert build["instances"] == len(geo.mesh_index)
    assert build["instanced_triangles"] == geo.triangle_count == stats["scene"]["triangles"]
    assert build["mesh_triangles"] == geo.mesh_triangle_count
    assert build["bytes"] == build["top_bytes"] + build["bottom_bytes"]
    assert build["top_bytes"] <= 200 * build["instances"]
    assert panel_row(addon, "Built As") == "two-level"
    assert panel_row(addon, "Unique Meshes") == str(len(geo.meshes))
    assert panel_row(addon, "Flattened Tris") == "{:,}".format(geo.triangle_count)
    assert panel_row(addon, "Top Nodes") == "{:,}".format(build["top_nodes"])
    assert panel_row(addon, "Mesh Nodes") == "{:,}".format(build["bottom_nodes"])
    assert panel_row(addon, "Tree") == "new"
    assert panel_row(addon, "Mesh Trees") == "{} built, 0 reused".format(len(geo.meshes))
    scene.bsplab.instances = "flatten"
    press(scene)
    assert panel_row(addon, "Built As") == "flatten"
    assert "Unique Meshes" not in panel_rows(addon)


def test_the_panel_offers_the_choice(addon, core, empty_scene):
    calls = draw(addon.build_render.panel.BSPLAB_PT_main)
    assert ("prop", "instances") in calls


# -----------------------------------------------------------------------------
# Re-use per mesh


def kept(addon):
    return addon.state.STATE.tree_cache.kept_tree()


def test_moving_adding_deleting_an_instance_rebuilds_the_top_level_only(addon, core,
                                                                        instanced_scene):
    scene = instanced_scene["scene"]
    press(scene)
    first = kept(addon)
    trees = {id(tree): tree for tree in first.meshes}
    assert press(scene)["build"]["reused"] is True and kept(addon) is first

    def check(n_instances):
        bpy.context.view_layer.update()
        build = press(scene)["build"]
        assert build["reused"] is False
        assert (build["mesh_trees_built"], build["mesh_trees_reused"]) == (0, len(trees))
        assert build["instances"] == n_instances
        assert panel_row(addon, "Tree") == "top rebuilt"
        # The very mesh trees of the first press.
        assert {id(tree) for tree in kept(addon).meshes} == set(trees)
        return build["instances"]

    n = first.stats["instances"]
    instanced_scene["grid"][4].location.x += 0.7  # move a collection instance
    check(n)
    instanced_scene["duplicates"][1].location.z += 0.3  # move a linked duplicate
    check(n)
    extra = utils.link(scene, "Grid extra", None, (6.0, 4.0, 0.0))  # add one
    extra.instance_type = 'COLLECTION'
    extra.instance_collection = instanced_scene["props"]
    n = check(n + 2)
    bpy.data.objects.remove(instanced_scene["duplicates"][0])  # delete one
    n = check(n - 1)
    instanced_scene["grid"][0].hide_set(True)  # hide a collection instance
    check(n - 2)


def test_editing_one_mesh_rebuilds_only_its_tree(addon, core, instanced_scene):
    scene = instanced_scene["scene"]
    press(scene)
    names = extract(addon).mesh_names
    before = list(kept(addon).meshes)
    shared = instanced_scene["shared"]
    shared.vertices[0].co.z += 0.2
    shared.update()
    bpy.context.view_layer.update()
    build = press(scene)["build"]
    assert (build["mesh_trees_built"], build["mesh_trees_reused"]) == (1, len(before) - 1)
    after = kept(addon).meshes
    changed = names.index("Duplicate 0")
    for i, (old, new) in enumerate(zip(before, after)):
        assert (new is old) == (i != changed), names[i]
    assert panel_row(addon, "Mesh Trees") == "1 built, {} reused".format(len(before) - 1)
    # A modifier on one collection object: that mesh only, again.
    instanced_scene["props"].objects["Prop Tetra"].modifiers.new("Subdivision", 'SUBSURF')
    bpy.context.view_layer.update()
    build = press(scene)["build"]
    assert build["mesh_trees_built"] == 1


def test_counting_the_builds(addon, core, instanced_scene, monkeypatch):
    """The same as the Tree identities, counted at the core: a moved
    instance calls bsplab.build not once; bsplab.build_instanced once."""
    scene = instanced_scene["scene"]
    press(scene)
    calls = {"build": 0, "build_instanced": 0}
    for name in calls:
        real = getattr(core, name)

        def counted(*args, _real=real, _name=name, **kwargs):
            calls[_name] += 1
            return _real(*args, **kwargs)
        monkeypatch.setattr(core, name, counted)
    instanced_scene["grid"][0].location.y -= 0.5
    bpy.context.view_layer.update()
    press(scene)
    assert calls == {"build": 0, "build_instanced": 1}


# -----------------------------------------------------------------------------
# Embree, the inspector and the overlay, errors


def test_embree_traces_the_flattened_scene(addon, core, instanced_scene):
    pytest.importorskip("embreex")
    scene = instanced_scene["scene"]
    scene.bsplab.compare_with_embree = True
    embree = press(scene)["embree"]
    if not embree["available"]:
        pytest.skip(embree["message"])
    assert embree["embree_triangles"] == extract(addon).triangle_count
    assert embree["compare"]["agreement"] >= 0.999
    assert panel_row(addon, "Embree Traced") == "flattened scene"
    assert panel_row(addon, "Hits Matched") == "by flat triangle"
    assert press(scene)["embree"]["embree_reused"] is True


def test_inspector_and_overlay_work_on_a_two_level_build(addon, core, instanced_scene):
    # What they show is test_two_level_views.py's; here only that a
    # two-level press no longer turns them away.
    scene = instanced_scene["scene"]
    press(scene)
    assert bpy.ops.bsplab.inspect_ray(origin=(0, -13, 7), direction=(0, 1, -0.4)) == {'FINISHED'}
    assert addon.state.STATE.inspection["structure"] == "two_level"
    overlay = addon.overlay
    scene.bsplab_overlay.show = True
    try:
        texts = [text for kind, text in draw(overlay.panel.BSPLAB_PT_overlay) if kind == "label"]
        assert overlay.panel.TWO_LEVEL_NOTE in texts
        assert overlay.draw.current_geometry(scene)["top_boxes"] > 0
    finally:
        scene.bsplab_overlay.show = False


def test_a_singular_instance_is_a_clear_error(addon, core, instanced_scene):
    from test_errors import assert_fails_cleanly
    instanced_scene["grid"][5].scale = (1.0, 1.0, 0.0)
    bpy.context.view_layer.update()
    message = assert_fails_cleanly(addon, instanced_scene["scene"], "matrix is singular")
    assert "in 'Grid 1 2'" in message
    assert "Instances: Flatten" in message
    # Flattened, the same scene builds: its triangles are merely flat.
    instanced_scene["scene"].bsplab.instances = "flatten"
    press(instanced_scene["scene"])


def test_leaf_culling_is_refused_in_two_levels(addon, core, instanced_scene):
    from test_errors import assert_fails_cleanly
    instanced_scene["scene"].bsplab.cull = True
    assert_fails_cleanly(addon, instanced_scene["scene"], "Leaf culling is not available")


@pytest.mark.parametrize("case", ["no_camera", "empty_scene", "empty_mesh"])
def test_scene_errors_in_two_levels(addon, core, case):
    from test_errors import assert_fails_cleanly
    scene = utils.reset_file("two_level")
    if case == "no_camera":
        build_instanced_scene(scene)
        scene.camera = None
        assert_fails_cleanly(addon, scene, "The scene has no active camera")
    elif case == "empty_scene":
        utils.add_camera(scene)
        assert_fails_cleanly(addon, scene, "No visible mesh in the scene")
    else:
        utils.add_camera(scene)
        utils.link(scene, "Empty Mesh", bpy.data.meshes.new("Empty"))
        assert_fails_cleanly(addon, scene, "have no faces")


def test_compare_b_in_two_levels(addon, core, instanced_scene):
    scene = instanced_scene["scene"]
    scene.bsplab_compare.enabled = True
    scene.bsplab_compare.method = "bvh"
    stats = press(scene)
    assert stats["b"]["build"]["structure"] == "two_level"
    assert stats["b"]["build"]["mesh_structure"] == "bvh"
    assert abs(stats["b"]["render"]["hits"] - stats["render"]["hits"]) <= 3
