"""Shared fixtures: the scenes every tree is checked on, loaded once."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from bsplab import io, scenes, workloads

SHARED = workloads.shared_scene_paths()
SCENE_IDS = [f"gen:{n}" for n in scenes.NAMES] + [f"shared:{p.stem}" for p in SHARED]


@functools.lru_cache(maxsize=None)
def load_scene(scene_id: str) -> np.ndarray:
    kind, name = scene_id.split(":", 1)
    if kind == "gen":
        return scenes.generate(name)
    return io.load_mesh(workloads.shared_scenes_dir() / f"{name}.ply")


@pytest.fixture(params=SCENE_IDS)
def scene(request) -> tuple[str, np.ndarray]:
    return request.param, load_scene(request.param)


def pytest_report_header(config):
    d = workloads.shared_scenes_dir()
    return f"shared scenes: {d} ({len(SHARED)} meshes)" if d else \
        "shared scenes: absent (their tests are skipped)"
