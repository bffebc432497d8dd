"""Scene extraction from the evaluated depsgraph."""

import bpy
import numpy as np
import pytest

import bsplab_test_utils as utils


def extract(addon):
    return addon.jobs.scene_reader.scene_triangles(bpy.context.evaluated_depsgraph_get())


def centroids(triangles):
    return triangles.mean(axis=1)


def test_triangle_count_equals_evaluated_scene(addon, test_scene):
    geometry = extract(addon)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert geometry.triangles.dtype == np.float32
    assert geometry.triangles.shape == (geometry.triangle_count, 3, 3)
    assert geometry.triangle_count == utils.evaluated_triangle_count(depsgraph)
    assert geometry.triangle_count == utils.EXPECTED_TRIANGLES
    # Cube and ground, plus two instances of the two props.
    assert geometry.instances == 2 + utils.PROP_INSTANCES * 2
    assert geometry.objects == 4  # cube, ground, tetra, card


def test_world_space_instances_and_exclusions(addon, test_scene):
    tris = extract(addon).triangles
    c = centroids(tris)
    for x in (-3.5, 3.5):
        near = np.abs(c[:, 0] - x) < 1.0
        assert near.sum() == utils.PROP_TRIANGLES, "instance at x={} in world space".format(x)
    # The subdivided cube sits at z in [0, 2] around the origin.
    cube = (np.abs(c[:, 0]) < 1.2) & (c[:, 2] > 0.01)
    assert cube.sum() == utils.SUBDIV_CUBE_TRIANGLES
    # The hidden blocker is the vertical plane y = -6: none of it is there.
    assert not np.any(np.all(np.abs(tris[:, :, 1] + 6.0) < 1e-4, axis=1))
    # The text object (at z = 3) has no characters: no faces.
    assert tris[:, :, 2].max() <= 2.0 + 1e-5


def test_modifier_changes_are_followed(addon, test_scene):
    test_scene["cube"].modifiers["Subdivision"].levels = 1
    geometry = extract(addon)
    assert geometry.triangle_count == utils.EXPECTED_TRIANGLES - utils.SUBDIV_CUBE_TRIANGLES + 6 * 4 * 2


def test_hidden_objects_excluded(addon, test_scene):
    n = extract(addon).triangle_count
    test_scene["ground"].hide_viewport = True
    test_scene["instancers"][0].hide_set(True)
    bpy.context.view_layer.update()
    assert extract(addon).triangle_count == n - utils.GROUND_TRIANGLES - utils.PROP_TRIANGLES


def test_vertex_instancing_hides_the_instancer(addon, empty_scene):
    """A mesh instancing its vertices, with "Show Instancer" off in the
    viewport, is not drawn itself (`show_self`); its child still is."""
    scene = empty_scene
    parent = utils.link(scene, "Parent", utils.make_mesh("Tri", [(0, 0, 0), (4, 0, 0), (0, 4, 0)],
                                                         [(0, 1, 2)]))
    child = utils.link(scene, "Child", utils.tetra_mesh("Child"))
    child.parent = parent
    parent.instance_type = 'VERTS'
    parent.show_instancer_for_viewport = False
    bpy.context.view_layer.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    geometry = extract(addon)
    assert geometry.triangle_count == utils.evaluated_triangle_count(depsgraph) == 3 * 4 + 4


def test_empty_scene_and_empty_mesh(addon, empty_scene):
    assert extract(addon).triangle_count == 0
    utils.link(empty_scene, "Points", utils.make_mesh("Points", [(0, 0, 0), (1, 0, 0)], []))
    geometry = extract(addon)
    assert geometry.triangle_count == 0
    assert geometry.triangles.shape == (0, 3, 3)


def test_shared_mesh_with_different_modifiers(addon, empty_scene):
    """Two objects share one mesh; only one has a modifier."""
    mesh = utils.cube_mesh("Shared")
    utils.link(empty_scene, "Plain", mesh, (-2, 0, 0))
    smooth = utils.link(empty_scene, "Smooth", mesh, (2, 0, 0))
    smooth.modifiers.new("Subdivision", 'SUBSURF').levels = 1
    bpy.context.view_layer.update()
    tris = extract(addon).triangles
    assert len(tris) == 12 + 48
    c = centroids(tris)
    assert (c[:, 0] < 0).sum() == 12
    assert (c[:, 0] > 0).sum() == 48


@pytest.mark.parametrize("scale", [1.0, 2.5])
def test_object_transform_applied(addon, empty_scene, scale):
    obj = utils.link(empty_scene, "Quad", utils.quad_mesh("Quad", 2.0), (10, 0, 0))
    obj.scale = (scale, scale, scale)
    obj.rotation_euler = (0, 0, np.pi / 2)
    bpy.context.view_layer.update()
    tris = extract(addon).triangles
    expected = np.array(obj.matrix_world, dtype=np.float64)
    corner = (expected @ np.array([1.0, 1.0, 0.0, 1.0]))[:3]
    assert np.min(np.linalg.norm(tris.reshape(-1, 3) - corner, axis=1)) < 1e-5
