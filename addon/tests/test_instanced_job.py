"""Build & Render's two-level builds (addon/build_render/job.py, tree_cache.py,
statistics.py) without Blender: the job on the core's instanced scenes
(bsplab.instanced_scenes) with the real core and Embree, the re-use of mesh
trees between presses, the statistics rows and the messages."""

import dataclasses

import numpy as np
import pytest

import bsplab
from bsplab import instanced_scenes
from bsplab.blender.extract import InstancedGeometry
from bsplab.blender.scene_camera import CameraSpec

from addon_without_blender import addon_module

jobs = addon_module("build_render.job")
tree_cache = addon_module("jobs.tree_cache")
statistics = addon_module("build_render.statistics")
worker = addon_module("jobs.worker")
messages = addon_module("jobs.messages")

KD_OPTIONS = {"threads": 2, "leaf_size": 1, "max_depth": 0, "leaf_boxes": "triangle"}


def geometry(meshes, mesh_index, matrices):
    """The InstancedGeometry the add-on's extraction would give."""
    meshes = [np.asarray(m, np.float32) for m in meshes]
    mesh_index = np.asarray(mesh_index, np.int64)
    matrices = np.asarray(matrices, np.float64)[:, :3, :]
    sizes = np.array([len(m) for m in meshes])
    return InstancedGeometry(
        meshes=meshes, mesh_index=mesh_index, matrices=matrices,
        instance_names=["'Object {}'".format(i) for i in range(len(mesh_index))],
        mesh_names=["Mesh {}".format(i) for i in range(len(meshes))],
        objects=len(mesh_index), instances=len(mesh_index),
        triangle_count=int(sizes[mesh_index].sum()), mesh_triangle_count=int(sizes.sum()))


def camera_of(geo, width=48, height=32):
    flat = geo.flatten().reshape(-1, 3)
    lo, hi = flat.min(axis=0), flat.max(axis=0)
    centre = (lo + hi) / 2
    eye = centre + np.array([1.0, -1.6, 0.9]) * float(np.linalg.norm(hi - lo))
    cam = bsplab.Camera.look_at(tuple(eye), tuple(centre), fov_deg=50)
    fields = {f.name: getattr(cam, f.name) for f in dataclasses.fields(bsplab.Camera)}
    return CameraSpec(width=width, height=height, name="TestCam", **fields)


def job_input(geo, cam, **changes):
    values = dict(triangles=None, instanced=geo, objects=geo.objects, instances=geo.instances,
                  camera=cam, method="kd", options=dict(KD_OPTIONS), mode="depth", threads=2,
                  cull=False, compare_with_embree=False, count_steps=True, scene_name="Scene")
    values.update(changes)
    return jobs.JobInput(**values)


def run(inp, cache=None):
    job = jobs.Job(bsplab, inp, cache=cache)
    job.start()
    job.join(120.0)
    assert not job.is_alive(), "the job did not end within 120 s"
    return job


def ok(inp, cache=None):
    job = run(inp, cache)
    assert job.error is None, job.error
    return job


@pytest.fixture(scope="module")
def transformed():
    return geometry(*instanced_scenes.transformed())


def test_two_level_job_renders_as_the_flattened_scene_and_agrees_with_embree(transformed):
    pytest.importorskip("embreex")
    cam = camera_of(transformed)
    two = ok(job_input(transformed, cam, compare_with_embree=True))
    flat = ok(job_input(transformed, cam, triangles=transformed.flatten(), instanced=None))
    stats = two.result["stats"]
    build = stats["build"]
    assert build["structure"] == "two_level" and build["mesh_structure"] == "bsp"
    assert build["meshes"] == len(transformed.meshes) == 2
    assert build["instances"] == len(transformed.mesh_index) == 60
    assert build["instanced_triangles"] == transformed.triangle_count == stats["scene"]["triangles"]
    assert build["mesh_triangles"] == transformed.mesh_triangle_count
    assert build["top_nodes"] > 0 and build["top_bytes"] > 0
    assert build["bottom_bytes"] + build["top_bytes"] == build["bytes"]
    assert (build["mesh_trees_built"], build["mesh_trees_reused"]) == (2, 0)
    # The mesh trees' quality, as the panel's Build rows say it.
    assert build["build_quality"] == KD_OPTIONS.get("build_quality", "exact")
    assert dict(statistics.build_rows(build))["Build Quality"] == build["build_quality"]
    assert flat.result["stats"]["build"]["structure"] == "bsp"
    # The same hits as one tree over the flattened triangles: the depth
    # images differ at most in a few pixels (edges, the transform's rounding).
    a, b = two.result["image"], flat.result["image"]
    assert two.result["stats"]["render"]["hits"] == pytest.approx(
        flat.result["stats"]["render"]["hits"], abs=3)
    assert (np.abs(a - b).max(axis=2) > 1e-3).sum() <= 3
    embree = stats["embree"]
    assert embree["available"], embree
    assert embree["compared"].startswith("two-level")
    assert embree["embree_triangles"] == transformed.triangle_count
    assert embree["compare"]["agreement"] >= 0.999
    rows = dict(statistics.embree_rows(embree))
    assert rows["Embree Traced"] == "flattened scene"
    assert rows["Hits Matched"] == "by flat triangle"
    # Judged exactly against the instances as given: nothing of ours wrong.
    assert rows["BSP Lab Wrong"] == rows["Undecided"] == "0"


def test_moving_adding_deleting_instances_rebuilds_the_top_level_only(transformed):
    cam = camera_of(transformed)
    cache = tree_cache.TreeCache()
    ok(job_input(transformed, cam), cache)
    kept = cache.kept_tree()
    meshes = list(kept.meshes)
    assert cache.mesh_tree_count() == 2
    again = ok(job_input(transformed, cam), cache)
    assert again.reused and cache.kept_tree() is kept

    moved = dataclasses.replace(transformed, matrices=transformed.matrices.copy())
    moved.matrices[5, :, 3] += (0.25, 0.0, 0.0)
    added = dataclasses.replace(
        transformed, mesh_index=np.append(transformed.mesh_index, 1),
        matrices=np.concatenate([transformed.matrices, transformed.matrices[:1]]),
        instance_names=transformed.instance_names + ["'Added'"])
    deleted = dataclasses.replace(transformed, mesh_index=transformed.mesh_index[1:],
                                  matrices=transformed.matrices[1:],
                                  instance_names=transformed.instance_names[1:])
    for geo in (moved, added, deleted):
        job = ok(job_input(geo, cam), cache)
        build = job.result["stats"]["build"]
        assert not job.reused
        assert (build["mesh_trees_built"], build["mesh_trees_reused"]) == (0, 2)
        assert build["instances"] == len(geo.mesh_index)
        scene = cache.kept_tree()
        assert scene is not kept
        # The very Tree objects of the first press, shared by the new scene.
        assert all(new is old for new, old in zip(scene.meshes, meshes))
        rows = dict(statistics.build_rows(build))
        assert rows["Tree"] == "top rebuilt"
        assert rows["Mesh Trees"] == "0 built, 2 reused"


def test_editing_one_mesh_rebuilds_only_its_tree(transformed):
    cam = camera_of(transformed)
    cache = tree_cache.TreeCache()
    ok(job_input(transformed, cam), cache)
    before = list(cache.kept_tree().meshes)
    edited = [m.copy() for m in transformed.meshes]
    edited[1][0, 0, 0] += 0.125
    job = ok(job_input(dataclasses.replace(transformed, meshes=edited), cam), cache)
    build = job.result["stats"]["build"]
    assert (build["mesh_trees_built"], build["mesh_trees_reused"]) == (1, 1)
    after = cache.kept_tree().meshes
    assert after[0] is before[0] and after[1] is not before[1]
    # Only this press's mesh trees are kept: the edited mesh's old tree is gone.
    assert cache.mesh_tree_count() == 2
    # A method change builds every mesh tree anew.
    job = ok(job_input(transformed, cam, method="bvh", options={"threads": 2}), cache)
    assert job.result["stats"]["build"]["mesh_trees_built"] == 2


def test_a_flat_press_forgets_the_mesh_trees(transformed):
    cam = camera_of(transformed)
    cache = tree_cache.TreeCache()
    ok(job_input(transformed, cam), cache)
    assert cache.mesh_tree_count() == 2
    ok(job_input(transformed, cam, triangles=transformed.flatten(), instanced=None), cache)
    assert cache.mesh_tree_count() == 0 and len(cache) == 1
    assert cache.kept_tree().structure == "bsp"


def test_identical_meshes_share_one_tree(transformed):
    twin = dataclasses.replace(transformed, meshes=transformed.meshes + [transformed.meshes[0].copy()],
                               mesh_index=np.append(transformed.mesh_index, 2),
                               matrices=np.concatenate([transformed.matrices,
                                                        transformed.matrices[:1]]),
                               mesh_names=transformed.mesh_names + ["Twin"])
    job = ok(job_input(twin, camera_of(twin)), tree_cache.TreeCache())
    build = job.result["stats"]["build"]
    assert build["mesh_trees_built"] == 2 and build["mesh_tree_count"] == 2
    assert build["meshes"] == 3


def test_a_singular_instance_is_named_in_the_message(transformed):
    bad = dataclasses.replace(transformed, matrices=transformed.matrices.copy())
    bad.matrices[7, :, 2] = 0.0  # scale 0 along z
    cache = tree_cache.TreeCache()
    job = run(job_input(bad, camera_of(transformed)), cache)
    assert isinstance(job.error, worker.UserError), job.error
    message = worker.error_message(bsplab, job.error)
    assert "'Object 7'" in message and "singular" in message
    assert "Instances: Flatten" in message
    # Refused before the long part: no mesh tree was built for it.
    assert cache.mesh_tree_count() == 0


def test_culling_is_refused_for_two_level_builds(transformed):
    for changes in ({"cull": True}, {"mode": "heat_culled"}):
        job = run(job_input(transformed, camera_of(transformed), **changes))
        assert isinstance(job.error, worker.UserError)
        assert "not available for two-level builds" in str(job.error)


def test_cancel_between_mesh_builds_keeps_the_finished_mesh_trees(transformed):
    cache = tree_cache.TreeCache()
    inp = job_input(transformed, camera_of(transformed))
    job = jobs.Job(bsplab, inp, cache=cache)
    real_build = bsplab.build
    calls = []

    def build_then_cancel(*args, **kwargs):
        calls.append(1)
        tree = real_build(*args, **kwargs)
        job.cancel()  # Esc right after the first mesh tree
        return tree

    job.bsplab = types_with(bsplab, build=build_then_cancel)
    job.a.bsplab = job.bsplab
    job.run()
    assert isinstance(job.error, bsplab.Cancelled), job.error
    assert len(calls) == 1
    assert cache.mesh_tree_count() == 1 and cache.kept_tree() is None
    # The next press builds the other mesh tree only.
    again = ok(job_input(transformed, camera_of(transformed)), cache)
    assert again.result["stats"]["build"]["mesh_trees_built"] == 1


def types_with(module, **replaced):
    """`module` with some attributes replaced (a namespace over it)."""
    class Proxy:
        def __getattr__(self, name):
            return replaced[name] if name in replaced else getattr(module, name)
    return Proxy()


def test_progress_runs_over_the_mesh_builds(transformed):
    inp = job_input(transformed, camera_of(transformed))
    job = jobs.Job(bsplab, inp, cache=tree_cache.TreeCache())
    seen = []
    real_build = bsplab.build

    def build_and_watch(*args, **kwargs):
        seen.append(job.fraction())
        return real_build(*args, **kwargs)

    job.bsplab = job.a.bsplab = types_with(bsplab, build=build_and_watch)
    job.run()
    assert job.error is None, job.error
    assert seen == sorted(seen) and seen[0] == 0.0 and 0.0 < seen[1] < 0.6
    assert job.fraction() == pytest.approx(1.0)


def test_instance_message():
    geo = geometry([np.eye(3, dtype=np.float32)[None]], [0, 0], np.tile(np.eye(4), (2, 1, 1)))
    geo.instance_names[1] = "'Cube' in 'Grid'"
    text = messages.instance_message("instance 1: its matrix is singular (determinant 0.0): it "
                                 "flattens the mesh", geo)
    assert "the instance of 'Cube' in 'Grid': its matrix is singular" in text
    assert "scaled to 0" in text
    assert messages.instance_message("top_bins must be ...", geo).endswith("top_bins must be ...")


def test_two_level_rows_show_both_levels():
    build = {"structure": "two_level", "method": "kd", "mesh_structure": "bsp", "reused": False,
             "mesh_trees_built": 3, "mesh_trees_reused": 1, "build_seconds": 0.25,
             "fingerprint_seconds": 0.001, "meshes": 4, "instances": 1200, "top_nodes": 2399,
             "top_bytes": 216000, "top_depth": 14, "bottom_nodes": 5000, "bottom_bytes": 80000,
             "bytes": 296000, "mesh_triangles": 9000, "instanced_triangles": 2700000}
    rows = dict(statistics.build_rows(build))
    assert rows["Built As"] == "two-level"
    assert rows["Structure"] == "BVH over split planes"
    assert rows["Tree"] == "new" and rows["Mesh Trees"] == "3 built, 1 reused"
    assert rows["Unique Meshes"] == "4" and rows["Instances"] == "1,200"
    assert rows["Top Nodes"] == "2,399" and rows["Top Memory"] == "210.9 KiB"
    assert rows["Mesh Nodes"] == "5,000" and rows["Mesh Memory"] == "78.1 KiB"
    assert rows["Flattened Tris"] == "2,700,000"
    assert dict(statistics.build_rows(dict(build, reused=True)))["Tree"] == "reused"
    flat = dict(statistics.build_rows({"structure": "bsp", "method": "kd"}))
    assert flat["Built As"] == "flatten" and "Top Nodes" not in flat
    # Statistics saved before the "structure" key: a flat tree's rows.
    assert dict(statistics.build_rows({"method": "kd"}))["Method"] == "kd"
