"""The instanced API's loose ends (issue 56): each a clear error naming what
is wrong, or a correct answer - indices outside the flattened scene, a
scene's description against what was built, options a given Tree was not
built with, no instances, an empty mesh, a nearly singular matrix."""

from __future__ import annotations

import numpy as np
import pytest

import bsplab
from bsplab import instanced_scenes

I = np.eye(4)[None, :3]


@pytest.fixture(scope="module")
def cube_scene():
    return bsplab.build_instanced([instanced_scenes.cube()], [0], I)


def test_instance_of_names_an_index_outside_the_flattened_scene(cube_scene):
    assert cube_scene.flat_triangles == len(cube_scene.flatten()) == 12
    # -1 is a miss (intersect's and Embree's prim): no instance.
    assert cube_scene.instance_of(np.array([0, 11, -1])).tolist() == [0, 0, -1]
    for bad, k in (([999, 12, -5], 0), ([3, 12], 1), ([-5], 0)):
        value = bad[k]
        with pytest.raises(ValueError, match=rf"flat_prim\[{k}\] = {value} is out of range: the "
                                             r"flattened scene has 12 triangles \(0\.\.11; -1: a miss\)"):
            cube_scene.instance_of(np.array(bad))
    with pytest.raises(TypeError, match="flat_prim must be integers"):
        cube_scene.instance_of(np.array([0.5]))


def test_instance_of_finds_each_instances_triangles():
    meshes, idx, mats = instanced_scenes.transformed(count=6)
    it = bsplab.build_instanced(meshes, idx, mats, "bvh")
    sizes = [len(meshes[i]) for i in idx]
    want = np.repeat(np.arange(6), sizes)
    assert it.instance_of(np.arange(it.flat_triangles)).tolist() == want.tolist()


def test_the_scene_says_the_method_its_mesh_trees_were_built_by():
    kd = bsplab.build(instanced_scenes.cube(), "kd")
    # method=None: the given Trees' method.
    it = bsplab.build_instanced([kd], [0], I)
    assert (it.stats["method"], it.stats["top_method"]) == ("kd", "bvh")
    assert repr(it).startswith("<bsplab.InstancedTree kd meshes, bvh top level: 1 meshes")
    # A kd tree described as a bvh scene is an error, not a wrong stats row.
    with pytest.raises(ValueError, match=r"mesh 0 is a kd tree, not bvh: a scene's mesh trees "
                                         r"share one method \(pass method='kd'"):
        bsplab.build_instanced([kd], [0], I, "bvh")
    bvh = bsplab.build(instanced_scenes.cube(), "bvh")
    with pytest.raises(ValueError, match="the given Trees are of methods bvh, kd"):
        bsplab.build_instanced([kd, bvh], [0, 1], np.repeat(I, 2, axis=0))
    # Triangles beside a Tree are built by the Tree's method.
    mixed = bsplab.build_instanced([bvh, instanced_scenes.cube()], [0, 1],
                                   np.repeat(I, 2, axis=0))
    assert [t.method for t in mixed.meshes] == ["bvh", "bvh"] and mixed.stats["method"] == "bvh"


def test_an_option_a_given_tree_was_not_built_with_is_named():
    wn = bsplab.build(instanced_scenes.cube(), "bsp_wn", k=6)
    with pytest.raises(ValueError, match=r"option k=5: mesh 0 is a Tree built with k=6"):
        bsplab.build_instanced([wn], [0], I, "bsp_wn", k=5)
    # What it was built with describes it (the add-on passes its options).
    it = bsplab.build_instanced([wn], [0], I, "bsp_wn", k=6, memory_limit_mb=64)
    assert it.meshes[0] is wn and it.options == {"k": 6, "memory_limit_mb": 64}
    # An option the method has not: named, whatever the meshes.
    with pytest.raises(TypeError, match="unknown build option.s. k for method 'kd'"):
        bsplab.build_instanced([bsplab.build(instanced_scenes.cube(), "kd")], [0], I, k=5)
    with pytest.raises(TypeError, match="unknown build option.s. k for method 'bvh'"):
        bsplab.build_instanced([instanced_scenes.cube()], [0], I, "bvh", k=5)


def test_the_top_levels_options_reach_it_and_are_checked():
    meshes, idx, mats = instanced_scenes.transformed(count=30)
    coarse = bsplab.build_instanced(meshes, idx, mats, "bvh", top_bins=2)
    fine = bsplab.build_instanced(meshes, idx, mats, "bvh", top_bins=64, top_intersect_cost=20.0)
    assert coarse.top_options["top_bins"] == 2 and fine.top_options["top_intersect_cost"] == 20.0
    assert coarse.stats["top_sah_cost"] != fine.stats["top_sah_cost"]
    with pytest.raises(ValueError, match="top_bins must be"):
        bsplab.build_instanced(meshes, idx, mats, "bvh", top_bins=257)
    with pytest.raises(ValueError, match="top_traversal_cost must be"):
        bsplab.build_instanced(meshes, idx, mats, "bvh", top_traversal_cost=0)


def test_no_instances_is_an_error_as_no_triangles_is():
    with pytest.raises(ValueError, match="no triangles to build a tree over"):
        bsplab.build(np.zeros((0, 3, 3), np.float32))
    with pytest.raises(ValueError, match="mesh_index is empty: there are no instances"):
        bsplab.build_instanced([instanced_scenes.cube()], [], np.zeros((0, 3, 4)))


def test_an_empty_mesh_is_named():
    empty = np.zeros((0, 3, 3), np.float32)
    with pytest.raises(ValueError, match="mesh 1: there are no triangles to build a tree over"):
        bsplab.build_instanced([instanced_scenes.cube(), empty], [0, 1],
                               np.repeat(I, 2, axis=0))


def test_a_nearly_singular_matrix_prints_its_determinant():
    m = np.repeat(I, 2, axis=0)
    m[1] = np.diag([1.0, 1.0, 1e-13, 1.0])[:3]
    with pytest.raises(ValueError, match=r"instance 1: its matrix is singular \(determinant "
                                         r"1e-13\)"):
        bsplab.build_instanced([instanced_scenes.cube()], [0, 0], m)
