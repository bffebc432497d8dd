"""Shared fixtures: the scenes every tree is checked on, loaded once. Also
the `slow` marker (the suite minus its fast part, which the sanitizer build
runs: `pytest -m "not slow"`) and the check that a sanitizer run really
imports the sanitized core."""

from __future__ import annotations

import contextlib
import functools
import os
import threading
from pathlib import Path

import numpy as np
import pytest

import bsplab
from bsplab import io, scenes, workloads

SHARED = workloads.shared_scene_paths()
SCENE_IDS = [f"gen:{n}" for n in scenes.NAMES] + [f"shared:{p.stem}" for p in SHARED]


@functools.lru_cache(maxsize=None)
def load_scene(scene_id: str) -> np.ndarray:
    kind, name = scene_id.split(":", 1)
    if kind == "gen":
        return scenes.generate(name)
    return io.load_mesh(workloads.shared_scenes_dir() / f"{name}.ply")


@contextlib.contextmanager
def cancelled_once_held(progress):
    """Cancels `progress` from another thread once the work it was given
    waits at the check `progress.hold_at_check(n)` named, so the cancel
    meets work that has provably not finished, whatever the machine's speed
    or load. Yields a list that gets the progress value seen there (empty
    when the work ended without reaching that check)."""
    seen, finished = [], threading.Event()

    def watch():
        while not progress.held and not finished.is_set():
            finished.wait(0.001)
        if progress.held:
            seen.append(progress.value)
            progress.cancel()

    watcher = threading.Thread(target=watch)
    watcher.start()
    try:
        yield seen
    finally:
        finished.set()
        watcher.join()


@pytest.fixture(params=SCENE_IDS)
def scene(request) -> tuple[str, np.ndarray]:
    return request.param, load_scene(request.param)


def pytest_report_header(config):
    d = workloads.shared_scenes_dir()
    return [f"shared scenes: {d} ({len(SHARED)} meshes)" if d else
            "shared scenes: absent (their tests are skipped)",
            f"bsplab core: {bsplab._core.__file__}"]


# The slow part: every case on a shared mesh; the agreement matrix on the
# larger generated scenes (its small room keeps every method at every K);
# the clipped-box check on the spheres; the build-determinism sweep over
# every method; the experiment runner's tests (Python bookkeeping around
# the same builds and traces). What is left (`-m "not slow"`) still builds
# every method and traces with and without culling; core/tools/sanitize.sh
# runs the part of it in SANITIZER_FILES under ASan + UBSan (6.1 min in one
# process in CI on 2026-12-05; `make test-sanitize` runs it in one
# pytest-xdist worker per core).
SLOW_TESTS = {
    "test_agreement.py::test_build_is_deterministic_across_thread_counts",
    "test_bsp.py::test_more_directions_find_cheaper_trees",
    "test_instanced.py::test_hits_agree_with_embree_on_the_flattened_scene",
}
SLOW_FILES = {"test_experiment.py"}
SLOW_ON_SCENES = {
    "test_agreement.py::test_hits_agree_with_embree": ("gen:spheres", "gen:fan"),
    "test_culling.py::test_clipped_boxes_agree_with_embree": ("gen:spheres",),
}


# The files whose fast part the sanitizer run keeps: those that drive the
# core's C++ (every builder, every kernel and path, culling, the in-plane
# walk, instancing, inspection, input checks, the ray order, the fuzzer) on
# small scenes.
# The others re-trace the same kernels on many more rays (test_agreement,
# test_ray_families, test_paths_agree, test_edge_robustness) or do their
# work in Python (the oracle's checks, the lab's bookkeeping, PLY files and
# images, the CLI's subprocesses, the add-on's jobs); at 3-5 times their
# time under ASan + UBSan they took most of CI's 90 minutes on its 2-core
# machine.
SANITIZER_FILES = {
    "test_bad_input.py", "test_bsp.py", "test_builder_parity.py", "test_bvh.py",
    "test_camera.py", "test_culling.py", "test_degenerate_warnings.py", "test_fuzz.py",
    "test_hits_only.py", "test_in_plane_walk.py", "test_instanced.py", "test_isa_levels.py",
    "test_kd_fast.py", "test_kd_only_traversal.py", "test_kd_tree.py", "test_leaf_simd.py",
    "test_memory_limit.py", "test_packets.py", "test_ray_order.py", "test_registry.py",
    "test_render_progress.py", "test_sweep_fast.py", "test_tree_geometry.py",
}

# Also slow under the sanitizers (core/tools/sanitize.sh sets
# BSPLAB_EXPECT_CORE): cases whose time there goes to Python-side checking
# or timing, not to core code the fast part leaves unsanitized. The cell
# tiling of whole trees (max_depth None) brute-forces every leaf cell in
# numpy; depths 0, 3 and 7 run the same C++ walk. The benchmark tables time
# paired traces (they run unsanitized in the core suite).
SANITIZER_SLOW_ON_PARAMS = {
    "test_tree_geometry.py::test_cells_of_a_level_tile_the_root_box": ("None-",),
    # Its rays come from 278,280 flattened triangles in numpy; the touching
    # cubes run every method through the same C++.
    "test_ray_order.py::test_spatial_order_in_an_instanced_scene_gives_the_counting_paths_hits":
        ("transformed-",),
}
SANITIZER_SLOW_TESTS = {
    "test_ray_order.py::test_a_batch_of_two_windows_comes_back_in_the_callers_order",
    "test_ray_order.py::test_an_instanced_batch_of_two_windows_comes_back_in_the_callers_order",
    "test_lab.py::test_bench_cull_pairs_culling_on_with_off",
    "test_lab.py::test_bench_writes_a_row_per_scene_and_method",
}


def is_slow(item) -> bool:
    name = f"{item.path.name}::{getattr(item, 'originalname', item.name)}"
    params = item.callspec.id if hasattr(item, "callspec") else ""
    if os.environ.get("BSPLAB_EXPECT_CORE") and (
            item.path.name not in SANITIZER_FILES
            or name in SANITIZER_SLOW_TESTS
            or any(s in params for s in SANITIZER_SLOW_ON_PARAMS.get(name, ()))):
        return True
    return ("shared:" in params or "shared_scene" in name or "shared_mesh" in name
            or name in SLOW_TESTS
            or item.path.name in SLOW_FILES
            or any(s in params for s in SLOW_ON_SCENES.get(name, ())))


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "slow: outside the fast part that the sanitizer build runs (conftest.is_slow)")


def pytest_collection_modifyitems(config, items):
    for item in items:
        if is_slow(item):
            item.add_marker(pytest.mark.slow)


def pytest_sessionstart(session):
    # core/tools/sanitize.sh sets this to the folder of its sanitized build.
    expected = os.environ.get("BSPLAB_EXPECT_CORE")
    if expected:
        got = Path(bsplab._core.__file__).resolve()
        if Path(expected).resolve() not in got.parents:
            pytest.exit(f"bsplab._core is {got}, not the build in {expected}", returncode=3)
